"""A printed summary never names a quantity with one unit and prints its value in another.

The machine names carry their SI unit (``theta_x_rad``, ``line_time_offset_s``: ``LineScanUnknowns.names``, the JSON
``names``); a summary prints values converted (arcsec, ms). So a summary line names the quantity bare and writes the
unit after the value — ``theta_x   +20.0927 ± 0.0846 arcsec`` (the frame ``estimate``), ``line_time_offset   1.8793 ±
0.1947 ms`` — or names it with the unit its value is printed in (``detectable thermal: sin_x_arcsec = 19.85``). The
fault this pins (the pushbroom summaries until 2026-11-28): ``theta_x_rad   20.0927 ± 0.0846 arcsec``,
``line_time_offset_s   1.8793 ± 0.1947 ms``, and a plan table headed ``line_time_offset_s`` over cells in ms.

``unit_mismatches`` reads two layouts: a name followed on its line by a value and a unit (``name  [σ|predicted σ|=|:]
value [± σ] unit``), and a table header naming columns whose cells, right-aligned under the name, end in a unit. It is
run on what the frame and pushbroom commands print on small shipped inputs: the pushbroom ``estimate``, ``plan`` (the
strip table), the roll search with its Monte Carlo check, the library's own ``Estimate.summary()`` of a pushbroom fit,
the frame ``estimate`` of a simulated pass with three floated effects, and the frame commands' printed summaries kept in ``tests/reference_outputs/`` (``estimate`` with a floated effect,
``diagnose``, ``plan``, ``montecarlo``, ``sensitivity``, ``reproduce``, ``ingest``; ``test_public_outputs`` keeps them
equal to what the commands print)."""

import re

import pytest
from paths import ROOT

#: a name's unit suffix -> the unit words a value in that unit is printed with
SUFFIX_UNITS = {
    "rad": {"rad"},
    "arcsec": {"arcsec", "″"},
    "deg": {"deg", "°"},
    "s": {"s"},
    "ms": {"ms"},
    "m": {"m"},
    "um": {"µm", "um"},
    "mm": {"mm"},
    "km": {"km"},
    "px": {"px"},
    "hz": {"Hz"},
}
UNIT_WORD = r"(arcsec|″|rad|deg|°|ms|µm|um|mm|km|m|s|px|Hz)(?![\w/])"
NUMBER = r"[+-]?\d+(?:\.\d*)?(?:e[+-]?\d+)?"
NAME = r"(?<![\w.])([A-Za-z][\w\[\]]*?)_(" + "|".join(SUFFIX_UNITS) + r")(?![\w\[])"
# a name, then (on its line) only spacing, ':', '=', 'σ' or 'predicted', a value, an optional '± σ', and a unit
VALUE_AFTER = re.compile(NAME + rf"(?:\s|[:=]|σ|predicted)*{NUMBER}(?:\s*±\s*{NUMBER})?\s*{UNIT_WORD}")
# a column's name in a table header: at the start of the line or two spaces after the previous column
HEAD = re.compile(r"(?:^|(?<=\s\s))" + NAME)
CELL_UNIT = re.compile(rf"{NUMBER}\s*{UNIT_WORD}\s*$")


def unit_mismatches(text):
    """[(line, name, printed unit)] where a name's unit suffix disagrees with the unit printed after its value, on its
    line or in the column it heads."""
    lines = text.splitlines()
    bad = []
    for i, line in enumerate(lines):
        for m in VALUE_AFTER.finditer(line):
            suffix, unit = m.group(2), m.group(3)
            if unit not in SUFFIX_UNITS[suffix]:
                bad.append((line, m.group(0).split()[0], unit))
        heads = [m for m in HEAD.finditer(line) if not re.match(rf"[\s:=σ]*{NUMBER}", line[m.end() :])]
        if len(heads) < 2:  # a table header names two columns or more
            continue
        for row in lines[i + 1 :]:
            if not row.strip():
                break
            for m in heads:
                cell = CELL_UNIT.search(row[m.start() : m.end()])
                if cell and cell.group(1) not in SUFFIX_UNITS[m.group(2)]:
                    bad.append((row, m.group(0), cell.group(1)))
    return bad


def test_the_check_finds_the_pushbroom_summaries_old_fault():
    """The check fails on the lines the pushbroom summaries printed before (a line and a table column), and passes
    their fixed form and a name that carries its printed unit."""
    old = [
        "  theta_x_rad                 20.0927 ± 0.0846 arcsec",
        "  line_time_offset_s           1.8793 ± 0.1947 ms   truth 2.0000   (-0.62 σ)",
        "  chip1_along_rad        σ 0.0212 arcsec",
        "  theta_y_rad            predicted σ    0.4645 arcsec   scatter    0.4310 arcsec",
        "chip1_along_rad +0.4328 ± 0.019 arcsec",
    ]
    for line in old:
        assert unit_mismatches(line), line
    table = (
        "strips (rolls)                     worst σθ″  line_time_offset_s         focal_scale     chip1_along_rad\n"
        "[0] (-25°)                         *  10.451           4.0122 ms            4.25e-06       0.0368 arcsec\n"
    )
    assert [b[1:] for b in unit_mismatches(table)] == [("line_time_offset_s", "ms"), ("chip1_along_rad", "arcsec")]
    fine = [
        "  theta_x                     20.0927 ± 0.0846 arcsec",
        "theta_x       +20.2997 ± 2.3004 arcsec",
        "time_tag      +0.002972 ± 0.0023 s (floated jointly with θ)",
        "detectable    thermal: sin_x_arcsec = 19.85, cos_y_arcsec = 19.85 (ρ = 0.992)",
        "low power       could not detect gnss_bias (radial_m) below 19 m (typical 10 m)",
        "unfitted at line_time_offset.dt_s = 0.001 it moves θy by -2.860″",
        table.replace("_s ", "   ").replace("_rad", "    "),
    ]
    for line in fine:
        assert not unit_mismatches(line), line


@pytest.fixture(scope="module")
def pushbroom_summaries(tmp_path_factory):
    """What the pushbroom commands print on the shipped ``pushbroom-campaign`` (θ, δt, κ, chip 1's offsets)."""
    from cli_run import run_cli

    out = tmp_path_factory.mktemp("plan")
    texts = {}
    for argv in (
        ["estimate", "pushbroom-campaign"],
        ["plan", "pushbroom-campaign"],
        ["plan", "pushbroom-campaign", "--target-arcsec", "0.5", "--target-chip-arcsec", "0.03", "--roll-step-deg", "30"]
        + ["--max-strips", "3", "--mc-check", "2", "--out", str(out)],
    ):
        code, printed, err = run_cli(argv)
        assert code == 0, (argv, err)
        texts[" ".join(argv[:2])] = texts.get(" ".join(argv[:2]), "") + printed
    return texts


def test_the_pushbroom_summaries_name_what_they_print(pushbroom_summaries):
    """Every unknown's line and table column of ``estimate`` and ``plan`` on a pushbroom campaign (the ones that printed
    ``theta_x_rad … arcsec`` and ``line_time_offset_s … ms``), with the unknowns present to be checked."""
    for argv, text in pushbroom_summaries.items():
        assert unit_mismatches(text) == [], argv
        for label in ("theta_x", "line_time_offset", "chip1_along"):
            assert re.search(rf"\b{label}\b", text), (argv, label)
    assert re.search(r"^  line_time_offset +[\d.]+ ± [\d.]+ ms", pushbroom_summaries["estimate pushbroom-campaign"], re.M)
    assert re.search(r"^  chip1_along +predicted σ +[\d.]+ arcsec", pushbroom_summaries["plan pushbroom-campaign"], re.M)


def test_the_librarys_summary_of_a_pushbroom_fit_names_what_it_prints():
    """``Estimate.summary()`` (and ``effects``' keys, ``joint_labels``) of a pushbroom fit: the quantity, whose unit is
    the value's (``chip1_along +0.4328 ± 0.019 arcsec``), as the frame fit's effects (``time_tag … s``)."""
    import numpy as np

    from boresight import estimate
    from boresight.observations.strip import simulate_strip_scenario, strip_noise_model, strip_unknowns
    from orbits.strip import load_strip_scenario

    sc = load_strip_scenario("pushbroom-campaign")
    strips = simulate_strip_scenario(sc, np.random.default_rng(np.random.SeedSequence(1)))
    est = estimate(strips, model=strip_noise_model(sc), unknowns=strip_unknowns(sc))
    text = est.summary()
    assert unit_mismatches(text) == [] and re.search(r"^chip1_along +[+-][\d.]+ ± [\d.]+ arcsec", text, re.M)
    # a dimensionless unknown has no unit and no gap where one would be (it ended 'focal_scale +2.9e-05 ± 1.6e-06 ')
    assert re.search(r"^focal_scale +[+-]\S+ ± \S+$", text, re.M), text
    assert set(est.effects) == {"line_time_offset", "focal_scale", "chip1_along", "chip1_across"}
    assert est.joint_labels[:4] == ("theta_x", "theta_y", "theta_z", "line_time_offset")
    assert est.effects["chip1_along"][0].unit == "arcsec" and est.effects["line_time_offset"][0].unit == "s"


def test_the_frame_estimate_prints_each_effect_with_its_unit(flight_obs, tmp_path):
    """``boresight estimate FILE --effects time_tag,focal_scale,gnss_bias`` (the kalman20 pass on WGS-84, seed 5): θ
    and every effect named bare with its unit after the values — ``time_tag … s``, ``gnss_bias … m`` — and a
    dimensionless one (``focal_scale``) with no unit and no double gap before its note."""
    from cli_run import run_cli

    path = tmp_path / "pass.ecsv"
    flight_obs.write(path)
    code, out, err = run_cli(["estimate", str(path), "--effects", "time_tag,focal_scale,gnss_bias"])
    assert code == 0, err
    assert unit_mismatches(out) == []
    assert re.search(r"^theta_x +[+-][\d.]+ ± [\d.]+ arcsec$", out, re.M)
    assert re.search(r"^time_tag +[+-]\S+ ± \S+ s \(floated", out, re.M)
    assert re.search(r"^gnss_bias +([+-]\S+ ± \S+, ){2}[+-]\S+ ± \S+ m \(floated", out, re.M)
    assert re.search(r"^focal_scale +[+-]\S+ ± \S+ \(floated", out, re.M), out


@pytest.mark.parametrize("case", sorted(p.name for p in (ROOT / "tests" / "reference_outputs").iterdir() if p.is_dir()))
def test_the_frame_commands_summaries_name_what_they_print(case):
    """The frame commands' printed summaries and reports (``tests/reference_outputs/<case>``: stdout and the Markdown
    they write), each line checked."""
    folder = ROOT / "tests" / "reference_outputs" / case
    texts = [p.read_text() for p in sorted(folder.iterdir()) if p.name == "stdout.txt" or p.suffix == ".md"]
    assert texts, case
    for text in texts:
        assert unit_mismatches(text) == [], case


def test_the_documented_outputs_name_what_they_print():
    """Every fenced block of the docs and the README (the tutorials' console blocks are what the commands print, checked
    by their tests; the pushbroom tutorial showed ``theta_x_rad … arcsec`` until 2026-11-28)."""
    docs = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]
    blocks = [(p.name, b) for p in docs for b in re.findall(r"```[a-z]*\n(.*?)```", p.read_text(encoding="utf-8"), flags=re.S)]
    assert len(blocks) > 50 and any(name == "tutorial-pushbroom.md" for name, _ in blocks)
    assert [(name, bad) for name, b in blocks for bad in unit_mismatches(b)] == []
