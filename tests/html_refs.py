"""The local files an HTML page links (src / href), for checking that reports link only files that exist."""

from __future__ import annotations

from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlparse


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.refs: list[tuple[str, str]] = []

    def handle_starttag(self, tag, attrs):
        self.refs += [(tag, v) for k, v in attrs if k in ("src", "href") and v and not v.startswith("#")]


def refs(page: Path) -> list[tuple[str, Path]]:
    """(tag, file) of every src / href of the page but #anchors; fails on absolute or network links."""
    p = _Refs()
    p.feed(page.read_text())
    out = []
    for tag, ref in p.refs:
        u = urlparse(ref)
        assert not u.scheme and not u.netloc and not ref.startswith("/"), f"not a relative link: {ref}"
        out.append((tag, (page.parent / unquote(u.path)).resolve()))
    return out


def local_refs(page: Path) -> list[Path]:
    """The files of refs(page)."""
    return [p for _, p in refs(page)]
