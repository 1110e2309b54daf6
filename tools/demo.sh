#!/usr/bin/env bash
# The main job, for now: simulate the default unit on the factory sequence, calibrate it both ways
# (AINS and NLSQ), print the parameter table, the evaluation metrics and the cross-check verdict.
# Usage: tools/demo.sh [SEQUENCE] [SEED]     (defaults: factory-std 1)
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
SEQ=${1:-factory-std}
SEED=${2:-1}
RUN=var/runs/demo-${SEQ}-${SEED}
mkdir -p var/runs
./build/bin/imucal simulate --sequence "$SEQ" --seed "$SEED" --out "$RUN" --overwrite
set +e
./build/bin/imucal calibrate "$RUN" --method all
rc=$?
set -e
echo "archive: $RUN (exit code $rc: 0 = PASS, 3 = REVIEW)"
exit $rc
