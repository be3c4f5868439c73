"""The pieces of `nerfkit eval` that are not rendering (scores end to end: tests/cli/test_main.py)."""

import pytest

from nerfkit.core.errors import ConfigError
from nerfkit.core.presets import preset
from nerfkit.evaluation.evaluate import (
    OUTLIER_DB,
    format_eval_table,
    refuse_chunk,
    split_slug,
    worst_views,
)


def test_split_slug_is_file_name_safe():
    assert split_slug("val[50:100]") == "val_50_100"
    assert split_slug("train,val[0:50]") == "train_val_0_50"
    assert split_slug("test") == "test"


def test_worst_views_flags_only_views_far_below_the_median():
    views = [{"view": k, "name": f"v{k}", "psnr": p} for k, p in enumerate([30.0, 29.0, 31.0, 30.5, 20.0])]
    worst = worst_views(views, k=2)
    assert [w["view"] for w in worst] == [4, 1]
    assert worst[0]["outlier"] and 30.0 - 20.0 > OUTLIER_DB  # 10 dB below the median
    assert not worst[1]["outlier"]  # 1 dB below
    assert worst_views([]) == []


def test_eval_table_lists_every_view_and_the_mean():
    result = {"per_view": [{"view": 0, "name": "r_0.png", "psnr": 25.0, "ssim": 0.9},
                           {"view": 1, "name": "r_1.png", "psnr": 27.0, "ssim": 0.92}],
              "n_views": 2, "step": 100, "psnr": 26.0, "ssim": 0.91}
    table = format_eval_table(result)
    assert "r_0.png" in table and "r_1.png" in table
    assert "(2 views, step 100)" in table and "26.00" in table


def test_chunk_is_refused_for_splats_only():
    refuse_chunk(preset("ngp"), 4096)
    with pytest.raises(ConfigError, match="--chunk has no effect on this run: its method renders whole images"):
        refuse_chunk(preset("splat"), 4096)
