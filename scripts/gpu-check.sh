#!/usr/bin/env bash
# Runs on a borrowed GPU machine (see the device tool): checks both GPU backends on real hardware
# and measures them. Expects release binaries built on the dev machine in devbin/ (cloth, and the
# conformance test binary as devbin/conformance) and the Vulkan loader's .deb files in .gl/.
# Writes its logs and CSVs under $OUT.
#
# Usage: bash scripts/gpu-check.sh [conformance] [stability] [study] [bench] [effects]
#        (default: conformance study bench)
#   conformance  the conformance suite with CI=1 (a missing adapter fails), and `cloth run` on each
#                GPU backend
#   study        `cloth study accuracy` on every backend, writing the report docs/accuracy.md
#                (and its CSV, SVG and PNG), copied to $OUT
#   stability    the stability suite's GPU cases (devbin/stability) with CI=1, then the soak at a
#                million substeps on each backend (SOAK_SECONDS each, default 200)
#   bench        `cloth bench` on both GPU backends: grids 32² to 2048², 16, 64 and scaled substeps
#   effects      `cloth bench --effects`: what each effect of scenes/flag.ron costs on both GPU backends
#                (EFFECT_GRIDS, default 128,512; EFFECT_SUBSTEPS, default the scene's own)
#   sweep        the kernels' tuning knobs, as FUSED:TILE:WORKGROUP:BLOCK (CLOTH_FUSED_SUBSTEPS,
#                CLOTH_TILE, CLOTH_WORKGROUP_SIZE, CLOTH_BLOCK_WIDTH; SWEEP overrides the list):
#                128² x 53, 1024² and 2048² x 64 on both backends, one CSV ($OUT/sweep.csv, a
#                `config` column first)
#   knobs        the same bench under several settings of the environment knobs, one after another
#                in one run (KNOBS: space-separated entries, each `base` or comma-separated
#                NAME=VALUE pairs, e.g. "base CLOTH_ALTERNATE_ORDER=0 CLOTH_ALTERNATE_ORDER=1,CLOTH_BLOCK_WIDTH=64";
#                KNOB_GRIDS, KNOB_SUBSTEPS, KNOB_FRAMES; KNOB_STATS=1 prints vulkano's registers;
#                the pseudo-knob CLOTH_BIN=path runs another build of cloth, carried beside devbin,
#                to compare builds in one run): one CSV ($OUT/knobs.csv, a quoted `knobs` column first)
set -uo pipefail
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
checks=${*:-conformance study bench}
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
# The conformance binary looks for the scenes where it was built.
mkdir -p /work && [ -e /work/main ] || ln -sfn "$PWD" /work/main
chmod +x devbin/*
{
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
  echo "== cloth backends"; devbin/cloth backends 2>&1
} | tee "$OUT/device.txt"
if [[ " $checks " == *" conformance "* ]]; then
  echo "== conformance (CI=1: a missing adapter fails)"
  CI=1 devbin/conformance --test-threads 4 2>&1 | tee "$OUT/conformance.txt" | grep -E "^test |test result|expected difference|panicked" | tail -70
  for b in wgpu vulkano; do
    echo "== cloth run --backend $b" | tee -a "$OUT/device.txt"
    devbin/cloth run --backend "$b" --json > "/tmp/run-$b.json" 2>&1
    grep -E '"(adapter|nan_count|max_penetration_fraction_of_radius|wall_ms_per_frame|submissions_per_frame|host_waits_per_frame)"' "/tmp/run-$b.json" | tee -a "$OUT/device.txt"
  done
fi
if [[ " $checks " == *" study "* ]]; then
  echo "== study accuracy (report: docs/accuracy.md)"
  devbin/cloth study accuracy --backends cpu,cpu-f64,wgpu,vulkano --report docs/accuracy.md 2>&1 | tee "$OUT/study.txt"
  cp docs/accuracy.md docs/accuracy.csv docs/accuracy.svg docs/accuracy.png "$OUT/"
fi
if [[ " $checks " == *" bench "* ]]; then
  echo "== bench"
  devbin/cloth bench --backends wgpu,vulkano --grids 32,128,512,1024,2048 --substeps 16,64,scaled --frames 20 --csv "$OUT/bench.csv" 2>&1 | tee "$OUT/bench.txt"
fi
if [[ " $checks " == *" stability "* ]]; then
  echo "== stability (GPU cases, CI=1)"
  CI=1 devbin/stability --test-threads 2 wgpu:: vulkano:: 2>&1 | tee "$OUT/stability.txt" | grep -E "^test |test result|panicked" | tail -60
  # GPU cases hold one lock (tests/src/lib.rs, gpu_lock), so the two backends' soaks run one after
  # the other: each gets its own box. Euler, Verlet and RK4 print within it on the H100; XPBD's
  # million substeps (about 10^8 dispatches) do not, and its line is not expected.
  : > "$OUT/soak.txt"
  for b in wgpu vulkano; do
    echo "== the soak at a million substeps on $b (${SOAK_SECONDS:-200} s at most)"
    CI=1 CLOTH_SOAK_SUBSTEPS=1000000 timeout "${SOAK_SECONDS:-200}" devbin/stability --nocapture "$b::soak" 2>&1 | tee -a "$OUT/soak.txt" | grep -E "substeps, energy|^test |test result|panicked"
  done
fi
if [[ " $checks " == *" effects "* ]]; then
  echo "== bench --effects"
  devbin/cloth bench --effects --backends wgpu,vulkano --grids "${EFFECT_GRIDS:-128,512}" \
    ${EFFECT_SUBSTEPS:+--substeps "$EFFECT_SUBSTEPS"} --frames 10 --csv "$OUT/effects.csv" 2>&1 | tee "$OUT/effects.txt"
fi
if [[ " $checks " == *" sweep "* ]]; then
  echo "== sweep: fused substeps : tile : workgroup size : block width"
  configs=${SWEEP:-"0:32x16:256:0 0:32x16:256:64 2:32x16:256:64 2:32x32:256:64"}
  : > "$OUT/sweep.csv"
  for c in $configs; do
    IFS=: read -r k tile wg block <<< "$c"
    CLOTH_FUSED_SUBSTEPS=$k CLOTH_TILE=$tile CLOTH_WORKGROUP_SIZE=$wg CLOTH_BLOCK_WIDTH=$block devbin/cloth bench \
      --backends wgpu,vulkano --grids ${SWEEP_GRIDS:-128,1024,2048} --substeps 53,64 --frames 20 --csv /tmp/sweep.csv > /tmp/sweep.txt 2>&1
    grep -E "refused|error" /tmp/sweep.txt | head -2 | sed "s|^|$c |"
    grep -E "^(wgpu|vulkano) " /tmp/sweep.txt | sed "s|^|$c |" | tee -a "$OUT/sweep.txt"
    if [ ! -s "$OUT/sweep.csv" ]; then sed -n 1p /tmp/sweep.csv | sed 's/^/config,/' > "$OUT/sweep.csv"; fi
    sed 1d /tmp/sweep.csv | sed "s|^|$c,|" >> "$OUT/sweep.csv"
  done
fi
if [[ " $checks " == *" knobs "* ]]; then
  echo "== knobs: the bench under each setting"
  : > "$OUT/knobs.csv"
  for c in ${KNOBS:-base}; do
    settings=()
    [ "$c" != base ] && IFS=, read -r -a settings <<< "$c"
    bin=devbin/cloth
    for setting in "${settings[@]}"; do [[ $setting == CLOTH_BIN=* ]] && bin=${setting#CLOTH_BIN=}; done
    chmod +x "$bin"
    env "${settings[@]}" CLOTH_PIPELINE_STATS=${KNOB_STATS:-0} "$bin" bench --backends wgpu,vulkano \
      --grids ${KNOB_GRIDS:-512,1024,2048} --substeps ${KNOB_SUBSTEPS:-64} --frames ${KNOB_FRAMES:-20} \
      --csv /tmp/knobs.csv > /tmp/knobs.txt 2>&1
    grep -E "refused|error|pipeline statistics" /tmp/knobs.txt | sort -u | head -16 | sed "s|^|$c |"
    grep -E "^(wgpu|vulkano) " /tmp/knobs.txt | sed "s|^|$c |" | tee -a "$OUT/knobs.txt"
    if [ ! -s "$OUT/knobs.csv" ]; then sed -n 1p /tmp/knobs.csv | sed 's/^/knobs,/' > "$OUT/knobs.csv"; fi
    sed 1d /tmp/knobs.csv | sed "s|^|\"$c\",|" >> "$OUT/knobs.csv"
  done
fi
