#!/usr/bin/env bash
# The device check of a GPU session, in one call (../shared/gpu/README.md; on the machine, after
# `bash ../shared/gpu/prepare.sh` here):  bash .device/device-run.sh bash tools/gpu_check.sh
# Renders the default scene at 1920x1080 with a GPU-length warm-up, checks vdmrender's reported times
# against an independent timer-query measurement (tools/timer_check.py), collects the golden images'
# statistics on this driver, then the billboard, VDM and molecule scenes. Everything lands in
# $OUT/gpu.tar.gz (packed after every step, so a step cut by its timeout keeps what came before).
set -u
R=/tmp/gpu; mkdir -p $R; OUT=${OUT:-/tmp/out}; mkdir -p $OUT
RES=${RES:-1920x1080}
TIMING="--warmup-s 1.5 --sample-s 0.5 --no-flip"
DEVICE=${DEVICE-cuda:0}; DEV=${DEVICE:+--device $DEVICE}
END=$(( $(date +%s) + ${BUDGET_S:-520} ))   # every step ends by then, whatever its own limit
pack() { tar czf $OUT/gpu.tar.gz -C $R . 2>/dev/null; }
step() {    # NAME LIMIT_S CMD...: run CMD for at most LIMIT_S (and never past END), log it, pack
  local name=$1 limit=$2; shift 2
  local left=$(( END - $(date +%s) )); [ $left -lt $limit ] && limit=$left
  [ $limit -le 5 ] && { echo "== $name skipped: no time left"; return; }
  echo "== $name ($(date +%T), at most $limit s)"; timeout $limit "$@" 2>&1 | tee $R/$name.log; pack
}
nvidia-smi -q -d CLOCK,PERFORMANCE > $R/nvidia-smi.txt 2>&1
scene() {   # NAME: bake configs/NAME.toml, render it here (the report, plot and overview sheets come back)
  vdmbake configs/$1.toml -o /tmp/$1.bundle && vdmrender /tmp/$1.bundle -o /tmp/r-$1 --resolution $RES $TIMING $DEV
  rc=$?; mkdir -p $R/$1; cp -r /tmp/r-$1/report.* /tmp/r-$1/error_vs_time.png /tmp/r-$1/overview $R/$1/ 2>/dev/null; return $rc
}
export -f scene; export R RES TIMING DEV
step default 150 bash -c "scene default"
step check-default 80 python3 tools/timer_check.py /tmp/default.bundle /tmp/r-default/report.json -o $R/check-default.json --frames 100 --warmup-s 1.5 $DEV
step golden 100 env VDM_GOLDEN_STATS=$R/golden.json VDM_GOLDEN_OUT=$R/golden-failures python3 -m pytest -q -p no:cacheprovider tests/test_golden.py
step vdm-torus-bricks 120 bash -c "scene vdm-torus-bricks"
step molecule-4jsv 80 bash -c "scene molecule-4jsv"
step billboards-bunny 120 bash -c "scene billboards-bunny"
ls -la $OUT
