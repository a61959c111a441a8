#!/usr/bin/env bash
# Run the approach-1 study with the ten independent GA fits (8 valves, 2 top
# mounts) JOBS at a time, then the rest of the pipeline. DVC 3 has no
# `dvc repro --jobs`, but concurrent `dvc repro <stage>` calls on different
# stages are safe (each updates its own dvc.lock entry).
#   JOBS=2 bash scripts/repro_parallel.sh
set -euo pipefail
cd "$(dirname "$0")/.."
dvc repro -q lab
dvc stage list --name-only | grep -E '^(flowbench|topmount)_fit@' | xargs -P "${JOBS:-2}" -n 1 dvc repro -q
dvc repro
