"""data_gen.half_copy: a half-float subset of a dataset that trains and scores like the original."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_dataset

from data_gen.half_copy import main
from nriqa.io.exr import read_exr, write_exr
from nriqa.io.manifest import read_datasets, read_manifest, write_manifest


def test_copy_keeps_the_chosen_records_and_rounds_values_to_half(tmp_path):
    src = make_dataset(tmp_path / "src", size=32)
    main([str(src), str(tmp_path / "dst"), "--no-twins"])
    records, meta = read_manifest(tmp_path / "dst")
    before, _ = read_manifest(src)
    assert {r.id for r in records} == {r.id for r in before if r.role != "twin"}
    assert all(r.twin is None for r in records) and meta["half_copy_of"] == str(src)
    for r in records:
        original = read_exr(src / r.path)
        copied = read_exr(tmp_path / "dst" / r.path)
        assert np.array_equal(copied, original.astype(np.float16).astype(np.float32))
    read_datasets(tmp_path / "dst")  # loads as a dataset: every path and reference is there


def test_a_value_beyond_half_range_is_one_line_and_no_manifest(tmp_path, capsys):
    src = make_dataset(tmp_path / "src", size=16, scenes=("alpha",), spps=(4,))
    records, _ = read_manifest(src)
    bright = next(r for r in records if r.role == "test")
    rgb = read_exr(src / bright.path)
    rgb[3, 3] = 1e6  # a firefly half floats cannot hold
    write_exr(src / bright.path, rgb)
    with pytest.raises(SystemExit) as exit_info:
        main([str(src), str(tmp_path / "dst")])
    assert "beyond half-float range" in str(exit_info.value) and bright.path in str(exit_info.value)
    assert not (tmp_path / "dst" / "manifest.json").exists()


def test_unknown_variant_is_one_line(tmp_path):
    src = make_dataset(tmp_path / "src", size=16, scenes=("alpha",), spps=(4,))
    with pytest.raises(SystemExit) as exit_info:
        main([str(src), str(tmp_path / "dst"), "--variants", "7"])
    assert "no record of variants [7]" in str(exit_info.value)


def test_an_empty_dataset_is_one_line(tmp_path):
    src = make_dataset(tmp_path / "src", size=16, scenes=("alpha",), spps=(4,))
    records, meta = read_manifest(src)
    write_manifest(src, [], meta)
    with pytest.raises(SystemExit) as exit_info:
        main([str(src), str(tmp_path / "dst")])
    assert "no record;" in str(exit_info.value)


def test_several_sources_make_one_dataset(tmp_path, capsys):
    first = make_dataset(tmp_path / "a", size=16, scenes=("alpha",), spps=(4,))
    second = make_dataset(tmp_path / "b", size=16, scenes=("beta",), spps=(4, 8))
    main([str(first), str(second), str(tmp_path / "dst"), "--no-twins"])
    records, meta = read_manifest(tmp_path / "dst")
    assert sorted(r.id for r in records) == ["alpha-4-test", "alpha-ref", "beta-4-test", "beta-8-test", "beta-ref"]
    assert meta["half_copy_of"] == [str(first), str(second)]
    read_datasets(tmp_path / "dst")  # every image of both sources is there
    assert "5 records" in capsys.readouterr().out


def test_sources_holding_the_same_records_are_refused_before_any_image(tmp_path):
    first = make_dataset(tmp_path / "a", size=16, scenes=("alpha",), spps=(4,))
    second = make_dataset(tmp_path / "b", size=16, scenes=("alpha",), spps=(4,))
    with pytest.raises(SystemExit) as exit_info:
        main([str(first), str(second), str(tmp_path / "dst")])
    message = str(exit_info.value)
    assert f"is also in {first}" in message and "hold different variants" in message
    assert not (tmp_path / "dst").exists()
