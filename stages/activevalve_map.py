"""DVC stage `activevalve_map`: the part's own active-valve P/Q map (no. 52)
from its active-valve bench record (conf/test/activevalve.yaml), on the
baseline design's map grid. With params.yaml `valve_map: part` (the default)
the study's damper-level fits and designs use it in place of the datasheet map
(`_common.study_design`); `valve_map: datasheet` keeps the supplier's map, as
the thesis' approach 1 (fig. 6.2). Outputs in
results/approach1/activevalve/: map.csv (a design's no. 52 file), map.json
(how far the part's valve lies from its datasheet, per current) and pq.png.

    python stages/activevalve_map.py
"""

import matplotlib.pyplot as plt

from _common import CONF, OUT, ROOT, baseline, measured_dir, stage, staged_dir, write_json
from dampertwin import report
from dampertwin.calibration.active_valve_map import map_change, map_from_record
from dampertwin.design import write_map
from dampertwin.io import read_record


def main() -> None:
    d = baseline()
    path = measured_dir() / "activevalve" / "baseline.parquet"
    name = str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)
    meas, meta = read_record(path, "activevalve", conf=CONF)
    built, moved = map_from_record(meas, d.pq_map, name)
    with staged_dir(OUT / "activevalve") as tmp:  # all outputs or none
        write_map(tmp / "map.csv", built)
        write_json(tmp / "map.json", {
            "record": name, "synthetic": bool(meta.get("synthetic", False)), "design_hash": d.hash(),
            "datasheet": d["active_valve.pq_map"],
            "note": "the part's active valve on its bench (map.csv, on the datasheet map's grid) against its "
                    "datasheet map; the study's fits and designs use map.csv with params.yaml valve_map: part",
            "change_from_datasheet": map_change(built, d.pq_map, moved)})
        fig = report.active_valve_map_figure(meas, built, d.pq_map, "active valve: the part on its bench vs its "
                                             "datasheet map")
        fig.savefig(tmp / "pq.png", dpi=100)
        plt.close(fig)


if __name__ == "__main__":
    stage(main, "activevalve_map")
