"""The data module's option checks: one line naming the key for every bad value, the same from both classes."""

import math

import pytest

from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.options import check_share, check_whole


@pytest.mark.parametrize("bad", [-1, 2.5, "many", math.nan, math.inf, True, None, [1]])
def test_a_whole_number_check_gives_one_line_naming_its_key(bad):
    with pytest.raises(ValueError, match=r"^data.ladder_span=.*: give a whole number of doublings >= 1$"):
        check_whole(bad, "ladder_span", 1, "doublings")


@pytest.mark.parametrize(("given", "low", "expected"), [(0, 0, 0), (3, 1, 3), (16.0, 0, 16), ("8", 1, 8)])
def test_a_whole_number_comes_back_as_an_int(given, low, expected):
    value = check_whole(given, "x", low, "things")
    assert value == expected and type(value) is int


@pytest.mark.parametrize("bad", [-0.1, 1.5, "half", math.nan, True, None])
def test_a_share_check_gives_one_line_naming_its_key(bad):
    with pytest.raises(ValueError, match=r"^data.cutmix_p=.* is not a probability; .*\(0 switches pasting off\)$"):
        check_share(bad, "cutmix_p", "pasting")


@pytest.mark.parametrize("good", [0, 0.0, 0.5, 1, "0.25"])
def test_a_share_comes_back_as_a_float(good):
    assert check_share(good, "x", "it") == float(good)


@pytest.mark.parametrize("bad", ["many", math.nan, False])
def test_the_data_module_names_a_bad_ladder_span(bad, synthetic_dataset):
    with pytest.raises(ValueError, match=r"^data.ladder_span=.*: give a whole number of doublings >= 1$"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", ladder_span=bad)
