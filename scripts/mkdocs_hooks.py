"""mkdocs hook: reference pages generated from the code and the committed files.

A page holds a marker ``<!-- generated: NAME -->``; ``on_page_markdown``
replaces it with the Markdown that ``GENERATORS[NAME]()`` returns:

- ``cli``: every subcommand's ``--help``, from ``dampertwin.cli.build_parser``;
- ``design-schema``: the design YAML schema, from ``dampertwin.design.schema``;
- ``config-groups``: every configuration group of ``conf/`` with its options;
- ``effects-table``: the effect library (``dampertwin.model.params.effects_table``);
- ``validation-approach1`` / ``validation-approach2``: the committed metrics and tables;
  ``validation-recovery`` / ``validation-discrepancy``: the committed recovery and discrepancy reports.

Registered in mkdocs.yml (``hooks:``); ``python scripts/mkdocs_hooks.py NAME`` prints one.
"""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:  # the checkout's code, also without an install
    sys.path.insert(0, str(ROOT / "src"))
MARKER = re.compile(r"<!-- generated: ([a-z0-9-]+) -->")


# ------------------------------------------------------------------ CLI
def cli() -> str:
    import argparse

    from dampertwin.cli import build_parser

    os.environ["COLUMNS"] = "100"  # stable wrapping of the help text
    ap = build_parser()
    out = ["## `dampertwin`", "", "```text", ap.format_help().rstrip(), "```", ""]

    def walk(parser: argparse.ArgumentParser, name: str) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, p in action.choices.items():
                    full = f"{name} {sub}"
                    out.extend([f"## `{full}`", "", "```text", p.format_help().rstrip(), "```", ""])
                    walk(p, full)

    walk(ap, "dampertwin")
    return "\n".join(out)


# ------------------------------------------------------------------ design schema
def _range(key: str) -> str:
    from dampertwin.design.schema import RANGES

    r = RANGES.get(key)
    return "-" if r is None else r.describe()


def design_schema() -> str:
    from dampertwin.design import schema as S

    out = ["### Types", "", "| type | meaning |", "|---|---|"]
    out += [f"| `{t}` | {S.TYPE_MEANING[t]} |" for t in S.TYPES]
    out += ["", "### SI units accepted", "", ", ".join(f"`{u}`" for u in sorted(S.SI_UNITS)), "",
            f"### The {len(S.PARAMETERS)} numbered parameters (thesis table 5.1)", "",
            "| no. | key | unit | kind | physical range |", "|---|---|---|---|---|"]
    for p in S.PARAMETERS:
        out.append(f"| {p.no} | `{p.group}.{p.name}` | `{p.unit}` | {p.kind} | {_range(f'{p.group}.{p.name}')} |")
    out += ["", "### Constants (`constants:`; types D or F)", "", "| name | unit | physical range |", "|---|---|---|"]
    out += [f"| `{k}` | `{u}` | {_range(f'constants.{k}')} |" for k, u in S.CONSTANTS.items()]
    out += ["", "### Effect switches (`effects:`, true / false)", "", "| effect | what it switches |", "|---|---|"]
    out += [f"| `{k}` | {v} |" for k, v in S.EFFECTS.items()]
    out += ["", "### Effect parameters (`effect_parameters:`)", "", "| key | unit | physical range |", "|---|---|---|"]
    out += [f"| `{k}` | `{u}` | {r.describe()} |" for k, (u, r) in S.EFFECT_PARAMETERS.items()]
    out += ["", "### Rules between parameters", "", "| smaller | larger | why |", "|---|---|---|"]
    out += [f"| `{a}` | `{b}` | {why}{'' if strict else ' (equal allowed)'} |" for a, b, strict, why in S.ORDERED]
    out += [f"| sum of {', '.join(f'`{k}`' for k in keys)} > 0 | | {why} |" for keys, why in S.POSITIVE_SUMS]
    out += ["", "### Active-valve P/Q map (parameter no. 52)", "",
            "A CSV file beside the YAML with the columns " + ", ".join(f"`{c}`" for c in S.MAP_COLUMNS) + "."]
    return "\n".join(out)


# ------------------------------------------------------------------ configuration groups
def _header(path: Path) -> str:
    """The leading comment block of a YAML file as one paragraph."""
    lines = []
    for line in path.read_text().splitlines():
        if line.startswith("# @package"):
            continue
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("#").strip())
    return " ".join(x for x in lines if x) or "-"


FULL_FILES = ("config.yaml", "compare.yaml", "sweep.yaml", "discrepancy.yaml")
FULL_GROUPS = ("profile", "calibration", "fit", "ofat", "hydra/launcher", "test")


def config_groups() -> str:
    conf = ROOT / "conf"
    out = ["## Top-level files", ""]
    for name in FULL_FILES:
        p = conf / name
        out += [f"### `conf/{name}`", "", _header(p), "", "```yaml", p.read_text().rstrip(), "```", ""]
    groups = sorted({p.parent.relative_to(conf).as_posix() for p in conf.rglob("*.yaml") if p.parent != conf})
    out += ["## Groups", ""]
    for g in groups:
        files = sorted((conf / g).glob("*.yaml"))
        out += [f"### `conf/{g}/`", ""]
        if g == "variant":
            out += ["The design cases of thesis table 6.5 (each names only what it changes).", "",
                    "| option | row | title | current [A] | overrides |", "|---|---|---|---|---|"]
            for p in files:
                d = yaml.safe_load(p.read_text())
                ov = ", ".join(f"`{k}` = {v}" for k, v in (d.get("overrides") or {}).items()) or "-"
                out.append(f"| `{p.stem}` | {d.get('row')} | {d.get('title')} | {d.get('current')} | {ov} |")
            out.append("")
            continue
        out += ["| option | what it is |", "|---|---|"]
        out += [f"| `{p.stem}` | {_header(p)} |" for p in files]
        out.append("")
        if g in FULL_GROUPS:
            for p in files:
                out += [f"??? note \"`conf/{g}/{p.name}`\"", "    ```yaml"]
                out += [f"    {line}" if line else "" for line in p.read_text().rstrip().splitlines()]
                out += ["    ```", ""]
    return "\n".join(out)


# ------------------------------------------------------------------ validation from committed results
def _g(x, spec: str) -> str:
    """A number from standard JSON (null: a non-finite value there) in ``spec`` format."""
    return "-" if x is None else format(x, spec)


def _metrics_table(metrics: dict) -> list[str]:
    rows = [(k, v) for k, v in sorted(metrics.items()) if isinstance(v, dict) and "mean_abs" in v]
    out = ["| metric | mean abs | max abs |", "|---|---|---|"]
    out += [f"| {k} | {_g(v['mean_abs'], '.3g')} | {_g(v['max_abs'], '.3g')} |" for k, v in rows]
    return out


def _code(metrics: dict) -> str:
    h = metrics.get("code_hash")
    return (f"Code hash of the source that wrote them: `{h}`." if h else
            "These results predate the `code_hash` field (they were written before it existed).")


def validation_approach1() -> str:
    a1 = ROOT / "results" / "approach1"
    m = json.loads((a1 / "metrics.json").read_text())
    fits = json.loads((a1 / "fits.json").read_text())
    out = [f"Generated from the committed `results/approach1/metrics.json` (profile `{fits.get('profile')}`). "
           + _code(m), "", *_metrics_table(m), "",
           f"Flagged cells: {m['flags']['count']} (thresholds "
           + ", ".join(f"{k} {v:g}" for k, v in m["flags"]["thresholds"].items()) + ")", ""]
    out += [f"- {c['case']}, {c['column']}: {c['cause']}" if "column" in c else f"- {c}" for c in m["flags"]["cells"]]
    out += ["", "### Fits (from `fits.json`)", "", "| fit | objective before | after | evaluations |",
            "|---|---|---|---|"]
    for n, f in fits["fits"].items():
        out.append(f"| {n} | {_g(f['objective_start'], '.4g')} | {_g(f['objective_best'], '.4g')} | "
                   f"{f['evaluations']} |")
    for t in ("table_6_5.md", "table_6_6.md"):
        out += ["", f"### `{t}`", "", (a1 / t).read_text().strip()]
    return "\n".join(out)


def validation_approach2() -> str:
    a2 = ROOT / "results" / "approach2"
    m = json.loads((a2 / "metrics.json").read_text())
    out = ["Generated from the committed `results/approach2/` files. " + _code(m), "",
           "```json", json.dumps(m, indent=2, sort_keys=True), "```"]
    for t in ("side_by_side.md", "table_7_1.md", "table_7_2.md", "verification.md"):
        out += ["", f"### `{t}`", "", (a2 / t).read_text().strip()]
    return "\n".join(out)


def validation_recovery() -> str:
    rec = ROOT / "results" / "recovery"
    m = json.loads((rec / "metrics.json").read_text())
    return "\n".join([f"Generated from the committed `results/recovery/` files. " + _code(m), "",
                      (rec / "recovery.md").read_text().strip()])


def validation_discrepancy() -> str:
    d = ROOT / "results" / "discrepancy"
    text = "\n".join(line for line in (d / "report.md").read_text().strip().splitlines()
                     if not line.startswith("!["))  # its figures: results/discrepancy/plots/
    return "\n".join(["Generated from the committed `results/discrepancy/report.md` (its figures are in "
                      "`results/discrepancy/plots/`).", "", text])


def effects_table() -> str:
    from dampertwin.design import load
    from dampertwin.model.params import effects_table as table

    return table(load(ROOT / "conf" / "design" / "baseline.yaml"))


GENERATORS = {"effects-table": effects_table, "cli": cli, "design-schema": design_schema, "config-groups": config_groups,
              "validation-approach1": validation_approach1, "validation-approach2": validation_approach2,
              "validation-recovery": validation_recovery, "validation-discrepancy": validation_discrepancy}


def on_page_markdown(markdown: str, page=None, config=None, files=None) -> str:  # mkdocs hook
    def sub(m: re.Match) -> str:
        name = m.group(1)
        if name not in GENERATORS:
            raise KeyError(f"{getattr(page, 'file', page)}: unknown generated section {name!r}")
        return GENERATORS[name]()

    return MARKER.sub(sub, markdown)


if __name__ == "__main__":
    print(GENERATORS[sys.argv[1]]())
