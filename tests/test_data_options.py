"""The data module's option checks: one line naming the key for every bad value, the same from both classes."""

import math

import pytest

from nriqa.data.datamodule import NRIQADataModule
from nriqa.data.options import check_names, check_range, check_share, check_whole


@pytest.mark.parametrize("bad", [-1, 2.5, "many", math.nan, math.inf, True, None, [1]])
def test_a_whole_number_check_gives_one_line_naming_its_key(bad):
    with pytest.raises(ValueError, match=r"^data.ladder_span=.*: give a whole number of doublings >= 1$"):
        check_whole(bad, "data.ladder_span", 1, "doublings")


@pytest.mark.parametrize("bad", [2.5, "many", math.inf, False])
def test_a_whole_number_with_no_bound_or_unit_reads_the_same_for_any_key(bad):
    # training's counts (trainer.max_epochs, seed) and nriqa-data's numbers give this line too
    with pytest.raises(ValueError, match=r"^trainer.max_epochs=.*: give a whole number$"):
        check_whole(bad, "trainer.max_epochs")
    assert check_whole(-3, "first_variant") == -3


@pytest.mark.parametrize(("given", "low", "expected"), [(0, 0, 0), (3, 1, 3), (16.0, 0, 16), ("8", 1, 8)])
def test_a_whole_number_comes_back_as_an_int(given, low, expected):
    value = check_whole(given, "data.x", low, "things")
    assert value == expected and type(value) is int


@pytest.mark.parametrize("bad", [-0.1, 1.5, "half", math.nan, True, None])
def test_a_share_check_gives_one_line_naming_its_key(bad):
    with pytest.raises(ValueError, match=r"^data.cutmix_p=.* is not a probability; .*\(0 switches pasting off\)$"):
        check_share(bad, "data.cutmix_p", "pasting")


@pytest.mark.parametrize("good", [0, 0.0, 0.5, 1, "0.25"])
def test_a_share_comes_back_as_a_float(good):
    assert check_share(good, "data.x", "it") == float(good)


@pytest.mark.parametrize("bad", ["many", math.nan, False])
def test_the_data_module_names_a_bad_ladder_span(bad, synthetic_dataset):
    with pytest.raises(ValueError, match=r"^data.ladder_span=.*: give a whole number of doublings >= 1$"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", ladder_span=bad)


@pytest.mark.parametrize(
    "bad", [[0, 0.5], [0.8, 0.3], [0.3, 4.5], [0.3, math.nan], [True, 2], 0.5, "ab", None, [0.3], [0.1, 0.2, 0.3]]
)
def test_a_range_check_gives_one_line_naming_its_key(bad):
    pattern = r"^data.pixel_filter_sigma=.*: give \[low, high\] with 0 < low <= high <= 4 pixels$"
    with pytest.raises(ValueError, match=pattern):
        check_range(bad, "data.pixel_filter_sigma", "pixels", 0, 4, low_open=True)


@pytest.mark.parametrize(
    ("given", "expected"), [([1, 1], (1.0, 1.0)), ((1.2, "2"), (1.2, 2.0)), ([3, 1e9], (3.0, 1e9))]
)
def test_a_range_comes_back_as_two_floats_and_a_closed_low_bound_admits_itself(given, expected):
    assert check_range(given, "data.albedo_line_period", "pixels", 1) == expected
    with pytest.raises(ValueError, match=r"^data.albedo_line_period=\[0.5, 2\]: give \[low, high\] with 1 <= low"):
        check_range([0.5, 2], "data.albedo_line_period", "pixels", 1)


@pytest.mark.parametrize("bad", [3, "ab", [2.0, 1.0]])
def test_the_data_module_names_a_bad_line_period_or_filter_range(bad, synthetic_dataset):
    with pytest.raises(ValueError, match=r"^data.albedo_line_period=.*: give \[low, high\]"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", albedo_line_period=bad)
    with pytest.raises(ValueError, match=r"^data.pixel_filter_sigma=.*: give \[low, high\]"):
        NRIQADataModule(synthetic_dataset, val_scene="beta", pixel_filter_sigma=bad)


def test_a_list_of_names_is_a_list_a_bare_name_or_none():
    assert check_names(["a", "b"], "data.scenes") == ["a", "b"] and check_names(("a",), "data.scenes") == ["a"]
    assert check_names("cornell", "data.scenes") == ["cornell"] and check_names(None, "data.scenes") is None
    assert check_names([], "data.scenes") == []
    for bad in (5, 2.5, {"a": 1}, True):
        with pytest.raises(ValueError, match=r"^data.scenes=.*: give a list of names, e.g. data.scenes=\[a,b\]$"):
            check_names(bad, "data.scenes")
