"""DVC stage `split_design`: one JSON per parameter group of the baseline
design (plus constants, effects and the P/Q map), so each downstream stage
depends on exactly the groups it uses and editing one valve reruns only
what depends on that valve."""

import hashlib

from _common import OUT, baseline, stage, write_json


def main() -> None:
    d = baseline()
    out = OUT / "params"
    for g in ("geometry", "oil", "third_tube", "top_mount", "piston_rebound", "piston_intake", "base_compression",
              "base_intake", "rod_friction"):
        write_json(out / f"{g}.json", {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.group(g).items()})
    write_json(out / "constants.json", {k: c.value for k, c in d.constants.items()})
    write_json(out / "effects.json", dict(d.effects))
    m = d.pq_map
    write_json(out / "active_valve.json", {"sha256": hashlib.sha256(m.flow.tobytes() + m.currents.tobytes()
                                                                     + m.dps.tobytes()).hexdigest()})


if __name__ == "__main__":
    stage(main, "split_design")
