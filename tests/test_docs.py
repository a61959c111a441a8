"""The documentation: `mkdocs build --strict` succeeds, and every code example
of README.md and docs/ runs as written on the files the repository ships.

An example is a fenced ``bash`` or ``python`` block. A block is left out only
when the line right before its fence is ``<!-- example: skip (reason) -->``
(the whole study, cluster commands, inputs made by ``dvc repro``); the reason
is required. Each example runs in a scratch folder that links the
repository's top-level entries, so it reads shipped files and writes under
``out/``; the checkout must be unchanged afterwards.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from conftest import ROOT

FENCE = re.compile(r"^```(bash|python)\n(.*?)^```", re.M | re.S)
SKIP = re.compile(r"<!-- example: skip \((?P<why>[^)]+)\) -->\s*$")
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def examples() -> list[tuple[str, int, str, str, str | None]]:
    """(file, line, language, code, skip reason or None) for every fenced bash / python block."""
    found = []
    for path in DOC_FILES:
        text = path.read_text()
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
            skip = SKIP.search(before)
            found.append((path.relative_to(ROOT).as_posix(), line, m.group(1), m.group(2),
                          skip.group("why") if skip else None))
    return found


RUNNABLE = [e for e in examples() if e[4] is None]


def _tracked() -> set[str]:
    r = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    return set(r.stdout.split()) if r.returncode == 0 else set()


def _status() -> str:
    r = subprocess.run(["git", "status", "--porcelain", "--untracked-files=all"], cwd=ROOT, capture_output=True,
                       text=True)
    return r.stdout if r.returncode == 0 else ""


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A folder whose entries link to the checkout's top-level entries (plus an empty out/)."""
    d = tmp_path_factory.mktemp("examples")
    for p in ROOT.iterdir():
        if p.name in (".git", "out", ".venv", "site") or p.name.startswith(".pytest"):
            continue
        (d / p.name).symlink_to(p, target_is_directory=p.is_dir())
    return d


def test_examples_are_found_and_skips_give_a_reason():
    ex = examples()
    assert len(RUNNABLE) >= 15, len(RUNNABLE)
    assert {f for f, *_ in RUNNABLE} >= {"README.md", "docs/tutorial/first-simulation.md",
                                         "docs/how-to/own-measurements.md", "docs/how-to/fit-submodel.md"}
    for f, line, _, _, why in ex:
        assert why is None or len(why.strip()) > 5, (f, line)
    # a marker that is not right before a fence would silently be ignored: forbid it
    for path in DOC_FILES:
        lines = path.read_text().splitlines()
        for i, l in enumerate(lines):
            if SKIP.search(l):
                assert i + 1 < len(lines) and lines[i + 1].startswith("```"), f"{path}:{i + 1}: marker without a block"


PATHLIKE = re.compile(r"(?<![\w/.-])((?:[\w.-]+/)*[\w.-]+\.(?:yaml|yml|csv|parquet|json|md|py|toml))\b")


@pytest.mark.parametrize("example", RUNNABLE, ids=[f"{f}:{n}" for f, n, *_ in RUNNABLE])
def test_examples_read_only_shipped_files(example):
    f, line, _, code, _ = example
    tracked = _tracked()
    if not tracked:
        pytest.skip("not a git checkout")
    for path in PATHLIKE.findall(code):
        if path.startswith("out/"):
            continue
        assert path in tracked or any(t.startswith(path.rstrip("/") + "/") for t in tracked), \
            f"{f}:{line}: {path} is not shipped (write outputs under out/)"


@pytest.mark.parametrize("example", RUNNABLE, ids=[f"{f}:{n}" for f, n, *_ in RUNNABLE])
def test_example_runs(example, scratch):
    f, line, lang, code, _ = example
    before = _status()
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT / "src"),
               PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    cmd = ["bash", "-euo", "pipefail", "-c", code] if lang == "bash" else [sys.executable, "-c", code]
    r = subprocess.run(cmd, cwd=scratch, capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, f"{f}:{line} failed (exit {r.returncode}):\n{r.stdout[-1500:]}\n{r.stderr[-3000:]}"
    assert _status() == before, f"{f}:{line} changed the checkout"


def test_mkdocs_build_strict(tmp_path):
    """The site builds with every warning an error (broken links, generated pages, API docstrings)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), NO_MKDOCS_2_WARNING="1")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                       cwd=ROOT, capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-4000:]
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "usage: dampertwin simulate" in cli and "usage: dampertwin design check" in cli  # generated
    schema = (tmp_path / "site" / "reference" / "design-schema" / "index.html").read_text()
    assert schema.count("<tr>") > 105 + 26  # every numbered parameter and constant
    assert "generated:" not in cli + schema  # no marker left unreplaced


def _side_by_side() -> dict[str, dict]:
    """results/approach2/side_by_side.md: per approach the summary row's figures and the 1.6 A rebound
    difference [%] of its table 7.1."""
    text = (ROOT / "results" / "approach2" / "side_by_side.md").read_text()
    out = {}
    for name in ("approach1", "approach2"):
        row = re.search(rf"^\| {name} \| ([^|]+) \| ([^|]+) \| ([^|]+) \|", text, re.M)
        block = re.search(rf"^### {name}\n\n(\|.*)\n\|.*\n(\| 1 \| 1\.6 \|.*)$", text, re.M)
        assert row and block, name
        head, first = ([c.strip() for c in line.strip("|").split("|")] for line in block.groups())
        out[name] = {"t71": float(row[1]), "t72": float(row[2]), "nrmse": float(row[3]),
                     "rebound_1.6": abs(float(first[head.index("Rebound difference [%]")]))}
    return out


def test_readme_approach_figures_are_the_committed_side_by_side():
    """The README's approach 1 vs 2 table and its 1.6 A rebound figures are the committed full run's
    (results/approach2/side_by_side.md) at the digits printed: a study rerun that moves them makes the
    README stale, and this test says so."""
    readme = (ROOT / "README.md").read_text()
    got = _side_by_side()
    for no, name in (("1", "approach1"), ("2", "approach2")):
        m = re.search(rf"^\| {no} \([^)]*\) \| ([\d.]+) % \| ([\d.]+) dB \| ([\d.]+) \|$", readme, re.M)
        assert m, f"README: the approach {no} row of the side-by-side table"
        for key, printed in zip(("t71", "t72", "nrmse"), m.groups()):
            digits = len(printed.split(".")[1]) if "." in printed else 0
            # the .md holds 3 decimals: printed to fewer, a value within half a printed digit (plus the .md's own
            # rounding, 0.0005) is the same figure (0.855 there may be 0.8552, printed 0.86)
            assert abs(float(printed) - got[name][key]) <= 0.5 * 10.0 ** -digits + 5e-4, (name, key, printed,
                                                                                          got[name][key])
    m = re.search(r"rebound peak at 1\.6 A (\d+) % off,\s+approach 1's (\d+) %", readme)
    assert m, "README: the 1.6 A rebound peak sentence"
    assert (int(m[1]), int(m[2])) == (round(got["approach2"]["rebound_1.6"]), round(got["approach1"]["rebound_1.6"]))


def test_sweeps_guide_trend_counts_are_the_committed_metrics():
    """docs/how-to/sweeps.md quotes the committed study's table-6.5 trend agreement (results/sweeps/
    metrics.json) against the thesis' measured and simulated columns: a rerun that moves them makes the
    guide stale, and this test says so."""
    import json

    m = json.loads((ROOT / "results" / "sweeps" / "metrics.json").read_text())
    text = " ".join((ROOT / "docs" / "how-to" / "sweeps.md").read_text().split())
    meas = re.search(r"committed full-profile study (\d+) of the (\d+) comparable directions agree", text)
    sim = re.search(r"SIMULATED column [^:]*published\.yaml`\): (\d+) of its (\d+) directions agree", text)
    assert meas and sim, "docs/how-to/sweeps.md: the two trend-agreement sentences"
    for found, key in ((meas, "table65_trend_agreement"), (sim, "table65_trend_agreement_thesis_simulated")):
        assert (int(found[1]), int(found[2])) == (m[key]["agree"], m[key]["compared"]), (key, found[0])


def test_approach2_guide_bound_hits_are_the_committed_metrics():
    """docs/explanation/approach2.md names the parameters that end on a search bound in the committed run
    (results/approach2/metrics.json `bound_hits`), with the side: a rerun that moves them makes it stale."""
    import json

    hits = json.loads((ROOT / "results" / "approach2" / "metrics.json").read_text())["bound_hits"]
    text = " ".join((ROOT / "docs" / "explanation" / "approach2.md").read_text().split())
    m = re.search(r"In the committed run \(the part's own active-valve map\) only (.+?) end on one", text)
    assert m, "docs/explanation/approach2.md: the committed run's bound-hit sentence"
    named = set(re.findall(r"([\w.]+) \((upper|lower)\)", m[1]))
    assert named == {(h["parameter"], h["bound"]) for h in hits}, (m[1], hits)


def test_readme_count_of_estimated_baseline_values_is_the_design_files():
    """The README's count of baseline values that are engineering estimates is that of
    conf/design/baseline.yaml's `source` lines."""
    import yaml

    params = yaml.safe_load((ROOT / "conf" / "design" / "baseline.yaml").read_text())["parameters"]
    n = sum("engineering estimate" in str(p.get("source", "")) for p in params)
    m = re.search(r"(\d+)\s+of the (\d+) in `conf/design/baseline.yaml` are engineering estimates",
                  " ".join((ROOT / "README.md").read_text().split()))
    assert m, "README: the sentence counting the estimated baseline values"
    assert (int(m[1]), int(m[2])) == (n, len(params))
