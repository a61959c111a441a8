"""OUT/report.md and OUT/plots/*.png of the discrepancy workflow (placeholder, filled below)."""


def write_report(out, design, problem, res, doc, args):
    lines = ["# Discrepancy report", "", f"Verdict: **{doc['verdict']}**", ""] + [f"- {l}" for l in res["log"]]
    (out / "report.md").write_text("\n".join(lines) + "\n")
