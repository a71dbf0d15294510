"""``boresight reproduce kiev2012``: the report keeps the Algorithm 1 section and adds ours."""

from __future__ import annotations

import pytest

from boresight.kiev2012 import report as rp


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("rep")
    return rp.generate("docs/reproduction.md", runs=600, seed=2, kalman_runs=20, workers=1, out_dir=None), out


def test_algorithm1_section_is_reproduced_verbatim(report):
    rep, _ = report
    assert rep.algorithm1_reproduced
    alg1_old = dict(rp.split_sections(open("docs/reproduction.md").read()))[rp.ALG1_HEADING]
    alg1_new = dict(rp.split_sections(rep.text))[rp.ALG1_HEADING]
    assert alg1_new.rstrip() == alg1_old.rstrip()


def test_report_has_eq28_and_kalman_sections_with_the_seminar_numbers(report):
    rep, _ = report
    heads = [h for h, _ in rp.split_sections(rep.text)]
    assert heads.count(rp.EQ28_HEADING) == 1 and heads.count(rp.KALMAN_HEADING) == 1
    eq28 = dict(rp.split_sections(rep.text))[rp.EQ28_HEADING]
    assert "| seminar | (not stated) | 6.09 | 6.09 | 8.36 | 11.98 |" in eq28
    for case in ("| A |", "| B |", "| C |"):
        assert case in eq28
    assert "| 20 | 4.6/4.3/6.4 |" in dict(rp.split_sections(rep.text))[rp.KALMAN_HEADING]


def test_regenerating_from_the_generated_report_is_stable(report, tmp_path):
    """The generated file is a valid template: our sections are replaced, not duplicated."""
    rep, _ = report
    p = tmp_path / "reproduction.md"
    p.write_text(rep.text)
    again = rp.generate(p, runs=600, seed=2, kalman_runs=20, workers=1)
    assert again.algorithm1_reproduced
    assert [h for h, _ in rp.split_sections(again.text)] == [h for h, _ in rp.split_sections(rep.text)]


def test_cli_writes_generated_file_when_alg1_tables_differ(tmp_path, capsys):
    """A template whose Algorithm 1 table was edited is not overwritten."""
    from boresight.cli import main

    text = open("docs/reproduction.md").read().replace("| 5 | 20.5 | 16.2 |", "| 5 | 20.5 | 99.9 |", 1)
    (tmp_path / "reproduction.md").write_text(text)
    rc = main(["reproduce", "kiev2012", "--out", str(tmp_path), "--runs", "300", "--kalman-runs", "10", "--workers", "1"])
    assert rc == 0
    assert (tmp_path / "reproduction.generated.md").exists()
    assert (tmp_path / "reproduction.md").read_text() == text
