"""core/outputs.staged_folder: a folder written in full or not at all."""

import errno

import pytest

from nerfkit.core.outputs import staged_folder


def _full_disk(folder, n):
    """Write n files into folder, then fail as a full disk does."""
    for k in range(n):
        (folder / f"f{k}.txt").write_text(f"new {k}")
    raise OSError(errno.ENOSPC, "No space left on device", str(folder / f"f{n}.txt"))


def test_a_new_folder_appears_only_when_every_file_is_written(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(OSError) as error:
        with staged_folder(out) as tmp:
            assert tmp.parent == out.parent and not out.exists()
            _full_disk(tmp, 3)
    assert error.value.filename == str(out / "f3.txt")  # the folder asked for, not the hidden one
    assert list(tmp_path.iterdir()) == []  # neither out, nor its .incomplete sibling, nor the folders above
    with staged_folder(out) as tmp:
        (tmp / "f0.txt").write_text("new 0")
        (tmp / "f1.txt").write_text("new 1")
    assert sorted(p.name for p in out.iterdir()) == ["f0.txt", "f1.txt"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]


def test_an_existing_folder_keeps_its_files_on_failure_and_gets_the_new_ones_on_success(tmp_path):
    out = tmp_path / "out"
    (out / "d0").mkdir(parents=True)
    (out / "d0" / "old.txt").write_text("old")
    (out / "f0.txt").write_text("old 0")
    (out / "mine.txt").write_text("the user's")
    with pytest.raises(OSError):
        with staged_folder(out) as tmp:
            _full_disk(tmp, 2)
    kept = {p.name: p.read_text() for p in out.iterdir() if p.is_file()}
    assert kept == {"f0.txt": "old 0", "mine.txt": "the user's"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with pytest.raises(KeyboardInterrupt):  # Ctrl-C half way
        with staged_folder(out) as tmp:
            (tmp / "f0.txt").write_text("new 0")
            raise KeyboardInterrupt
    assert (out / "f0.txt").read_text() == "old 0"
    with staged_folder(out) as tmp:
        (tmp / "f0.txt").write_text("new 0")
        (tmp / "f1.txt").write_text("new 1")
        (tmp / "d0").mkdir()  # a folder of the same name (eval's levels): merged, file by file
        (tmp / "d0" / "new.txt").write_text("new")
    assert {p.name: p.read_text() for p in out.iterdir() if p.is_file()} == {"f0.txt": "new 0", "f1.txt": "new 1",
                                                                             "mine.txt": "the user's"}
    assert sorted(p.name for p in (out / "d0").iterdir()) == ["new.txt", "old.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("writer", ["staged_folder", "write_together", "replace_with"])
def test_a_ctrl_c_just_after_the_folder_is_made_leaves_nothing(tmp_path, monkeypatch, writer):
    """A Ctrl-C that lands the moment a mkdir returns (before the write's own clean-up was armed) left the hidden
    folder (or the folders made for a file) behind; a Ctrl-C in the write leaves no temporary file."""
    from pathlib import Path

    from nerfkit.core.outputs import replace_with
    from nerfkit.export.files import write_together

    mkdir = Path.mkdir

    def mkdir_then_interrupted(self, *args, **kwargs):
        mkdir(self, *args, **kwargs)
        raise KeyboardInterrupt

    target = tmp_path / "new" / "out.txt"
    with pytest.raises(KeyboardInterrupt):
        if writer == "staged_folder":
            monkeypatch.setattr(Path, "mkdir", mkdir_then_interrupted)
            with staged_folder(tmp_path / "new"):
                pass
        elif writer == "write_together":
            monkeypatch.setattr(Path, "mkdir", mkdir_then_interrupted)
            write_together([(target, lambda p: p.write_text("x"))])
        else:
            target.parent.mkdir()

            def write(p):
                p.write_text("half")
                raise KeyboardInterrupt

            replace_with(target, write)
    monkeypatch.undo()
    left = sorted(p.name for p in tmp_path.rglob("*"))
    assert left == (["new"] if writer == "replace_with" else []), left
