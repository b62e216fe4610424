"""Result tables: Markdown for people (NaN as a dash), CSV for machines (NaN kept)."""

import csv
import math

import pytest

from nriqa.io.tables import markdown_table, read_csv, write_csv


def test_markdown_table_formats_floats_booleans_missing_and_undefined_cells():
    rows = [{"name": "a", "pcc": 0.98765, "ok": True}, {"name": "b", "pcc": math.nan, "ok": False}]
    lines = markdown_table(rows, ["name", "pcc", "ok", "absent"]).splitlines()
    assert lines[0] == "| name | pcc | ok | absent |"
    assert lines[2] == "| a | 0.988 | yes |  |"
    assert lines[3] == "| b | – | no |  |"
    assert "nan" not in "\n".join(lines).lower()


def test_csv_keeps_nan_for_machines(tmp_path):
    write_csv(tmp_path / "t.csv", [{"name": "b", "pcc": math.nan}], ["name", "pcc"])
    (row,) = list(csv.DictReader((tmp_path / "t.csv").open()))
    assert math.isnan(float(row["pcc"]))


def test_read_csv_checks_the_columns_and_says_what_file_it_wanted(tmp_path):
    write_csv(tmp_path / "t.csv", [{"name": "b", "pcc": 0.5}], ["name", "pcc"])
    assert read_csv(tmp_path / "t.csv", {"name"}, "a table") == [{"name": "b", "pcc": "0.5"}]
    with pytest.raises(ValueError, match=r"t.csv is not a table \(need columns name, srocc\)"):
        read_csv(tmp_path / "t.csv", {"name", "srocc"}, "a table")
    with pytest.raises(ValueError, match=r"cannot read .*nothing.csv \(No such file or directory\); give a table"):
        read_csv(tmp_path / "nothing.csv", {"name"}, "a table")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(ValueError, match="empty.csv is not a table"):
        read_csv(tmp_path / "empty.csv", {"name"}, "a table")
