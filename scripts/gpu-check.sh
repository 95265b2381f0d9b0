#!/usr/bin/env bash
# Checks both GPU backends on the GPU of this machine and measures them: the checks CI cannot run
# (CI has only lavapipe, a CPU implementation of Vulkan) and the figures of docs/performance.md.
#
# Usage: bash scripts/gpu-check.sh [conformance] [stability] [bench] [effects] [tuning] [compare]
#                                   [compare-self] [peer] [study]
#        (default: conformance bench)
#
#   conformance  the conformance suite and the block-order test with CI=1 (a missing adapter
#                fails), then `cloth run` on each GPU backend
#   stability    the stability suite's GPU cases with CI=1, the collider and self-collision cases
#                at their scenes' own size on every backend, the drape and the stiff drape at 256²
#                and one substep a frame with backward Euler and VBD, then the soak at a million
#                substeps on each backend (SOAK_SECONDS each, default 200: XPBD's million substeps
#                do not end in that; 0 skips the soak)
#   bench        `cloth bench` on both GPU backends: grids 32² to 2048², 16, 64 and scaled substeps;
#                then semi-implicit Euler, backward Euler and VBD at 256² and 1024², 1 and 16 substeps
#   effects      `cloth bench --effects`: what each effect of scenes/flag.ron costs (EFFECT_GRIDS,
#                default 128,512), each collider kind of scenes/colliders.ron
#                (COLLIDER_EFFECT_GRIDS, default 256), and self-collision on
#                scenes/self_collision_bench.ron (SELF_EFFECT_GRIDS, default 256,1024), with
#                `cloth profile` of that scene's timed frames with and without self-collision
#   tuning       the bench at 512², 1024² and 2048² × 64 under each GPU tuning in TUNINGS (a list
#                separated by ';' of `cloth bench` flags; default: the defaults, then block widths
#                32 and 128, workgroups of 128 and 512, forward and alternating block orders)
#   compare      the bench rows of docs/performance.md (128² × 53, 1024² and 2048² × 64) with this
#                build and with the build at OTHER_CLOTH, by turns, ROUNDS times (default 2)
#   compare-self the self-collision rows of `cloth bench --effects` on scenes/self_collision_bench.ron
#                (SELF_EFFECT_GRIDS, default 256,1024) with this build and with the build at
#                OTHER_CLOTH, by turns, ROUNDS times (default 2), and each build's `cloth profile`
#                of those frames on vulkano (compare-self-profile.txt)
#   peer         NVIDIA Warp's own cloth benchmark and its CuPy and PyTorch versions on the same
#                grids (scripts/peer-cloth.py; warp-lang 1.0.2 must be importable; PEER_GRIDS,
#                default 128,1024,2048)
#   study        `cloth study accuracy` on every backend, writing docs/accuracy.md and its data
#
# The binaries: CLOTH (default target/release/cloth) and, for conformance and stability, the test
# binaries CONFORMANCE, BLOCK_ORDER and STABILITY (default: built with cargo, when there is one).
# Logs and CSVs go to OUT (default gpu-check-out/).
set -uo pipefail
OUT=${OUT:-gpu-check-out}
CLOTH=${CLOTH:-target/release/cloth}
checks=${*:-conformance bench}
for check in $checks; do
  case $check in
    conformance | stability | bench | effects | tuning | compare | compare-self | peer | study) ;;
    *) echo "gpu-check: unknown check '$check' (the checks: conformance stability bench effects tuning compare compare-self peer study)" >&2; exit 2 ;;
  esac
done
mkdir -p "$OUT"

# A test binary: the one named in the variable, else the one cargo builds.
test_binary() {
  local given=$1 test=$2
  if [ -n "$given" ]; then echo "$given"; return; fi
  cargo test --release -p cloth-conformance --test "$test" --no-run --message-format=json 2>/dev/null |
    sed -n 's/.*"executable":"\([^"]*\)".*/\1/p' | tail -1
}

{
  command -v nvidia-smi > /dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
  echo "== cloth backends"; "$CLOTH" backends 2>&1
} | tee "$OUT/device.txt"

if [[ " $checks " == *" conformance "* ]]; then
  echo "== conformance (CI=1: a missing adapter fails)"
  CI=1 "$(test_binary "${CONFORMANCE:-}" conformance)" --test-threads 4 2>&1 | tee "$OUT/conformance.txt" |
    grep -E "^test |test result|expected difference|panicked" | tail -80
  CI=1 "$(test_binary "${BLOCK_ORDER:-}" block_order)" 2>&1 | tee "$OUT/block_order.txt" | grep -E "^test |test result"
  for b in wgpu vulkano; do
    echo "== cloth run --backend $b" | tee -a "$OUT/device.txt"
    "$CLOTH" run --backend "$b" --json 2>&1 |
      grep -E '"(adapter|nan_count|max_penetration_fraction_of_radius|wall_ms_per_frame|submissions_per_frame|host_waits_per_frame)"' | tee -a "$OUT/device.txt"
  done
fi

if [[ " $checks " == *" stability "* ]]; then
  stability=$(test_binary "${STABILITY:-}" stability)
  echo "== stability (GPU cases, CI=1)"
  CI=1 "$stability" --test-threads 2 wgpu:: vulkano:: 2>&1 | tee "$OUT/stability.txt" | grep -E "^test |test result|panicked" | tail -60
  echo "== stability: the collider and self-collision scenes at their own size (CLOTH_FULL_SIZE)"
  CI=1 CLOTH_FULL_SIZE=1 "$stability" --test-threads 2 --nocapture floor tilted cloth_falls heap twist folded sliding 2>&1 |
    tee "$OUT/stability-full.txt" | grep -E "^test |test result|panicked|penetration|self-intersections" | tail -80
  echo "== the drape and the stiff drape at 256², one substep a frame, with the implicit integrators"
  for scene in drape stiff_drape; do
    for integrator in backward-euler vbd; do
      # The stiff drape at this step needs VBD's multigrid correction before every sweep
      # (docs/performance.md).
      solver='()'
      [ "$scene/$integrator" = stiff_drape/vbd ] && solver='(vbd_multigrid_every: 1)'
      for b in wgpu vulkano; do
        echo "-- $scene $integrator $b $solver" | tee -a "$OUT/implicit-256.txt"
        "$CLOTH" run "scenes/$scene.ron" --backend "$b" --grid 256x256 --substeps 1 --frames 120 \
          --integrator "$integrator" --solver "$solver" --json 2>&1 |
          grep -E '"(peak_j|nan_count|max_penetration_fraction_of_radius|wall_ms_per_frame|newton|cg|vbd)"' |
          tee -a "$OUT/implicit-256.txt"
      done
    done
  done
  [ "${SOAK_SECONDS:-200}" = 0 ] || for b in wgpu vulkano; do
    echo "== the soak at a million substeps on $b (${SOAK_SECONDS:-200} s at most)"
    CI=1 CLOTH_SOAK_SUBSTEPS=1000000 timeout "${SOAK_SECONDS:-200}" "$stability" --nocapture "$b::soak" 2>&1 |
      tee -a "$OUT/soak.txt" | grep -E "substeps, energy|^test |test result|panicked"
  done
fi

if [[ " $checks " == *" bench "* ]]; then
  echo "== bench"
  "$CLOTH" bench --backends wgpu,vulkano --grids 32,128,512,1024,2048 --substeps 16,64,scaled --frames 20 \
    --csv "$OUT/bench.csv" 2>&1 | tee "$OUT/bench.txt"
  echo "== bench: the implicit integrators at their default solver settings"
  "$CLOTH" bench --backends wgpu,vulkano --grids 256,1024 --substeps 1,16 --integrators euler,backward-euler,vbd \
    --frames 5 --repeats 3 --csv "$OUT/bench-implicit.csv" 2>&1 | tee "$OUT/bench-implicit.txt"
fi

if [[ " $checks " == *" effects "* ]]; then
  echo "== bench --effects"
  "$CLOTH" bench --effects --backends wgpu,vulkano --grids "${EFFECT_GRIDS:-128,512}" --frames 10 \
    --csv "$OUT/effects.csv" 2>&1 | tee "$OUT/effects.txt"
  echo "== bench --effects on scenes/colliders.ron (a row for each collider kind)"
  "$CLOTH" bench --effects --scene scenes/colliders.ron --backends wgpu,vulkano --grids "${COLLIDER_EFFECT_GRIDS:-256}" \
    --frames 10 --csv "$OUT/effects-colliders.csv" 2>&1 | tee "$OUT/effects-colliders.txt"
  echo "== bench --effects on scenes/self_collision_bench.ron (the self-collision row)"
  "$CLOTH" bench --effects --scene scenes/self_collision_bench.ron --backends wgpu,vulkano \
    --grids "${SELF_EFFECT_GRIDS:-256,1024}" --frames 10 --csv "$OUT/effects-self.csv" 2>&1 | tee "$OUT/effects-self.txt"
  echo "== profile of scenes/self_collision_bench.ron, frames 2 to 51, with and without self-collision"
  sed 's/, *SelfCollision\]/]/' scenes/self_collision_bench.ron > "$OUT/self_collision_bench_without.ron"
  grids=${SELF_EFFECT_GRIDS:-256,1024}
  for n in ${grids//,/ }; do
    for b in wgpu vulkano; do
      for scene in scenes/self_collision_bench.ron "$OUT/self_collision_bench_without.ron"; do
        "$CLOTH" profile "$scene" --backend "$b" --grid "${n}x$n" --skip 1 --frames 50 \
          --csv "$OUT/profile-$b-$n-$(basename "$scene" .ron).csv" 2>&1 | grep -v '^wrote' | tee -a "$OUT/profile-self.txt"
      done
    done
  done
fi

# Runs the bench with the binary $1 and the flags $3.., labelling its CSV rows with $2.
labelled_bench() {
  local bin=$1 label=$2 csv=$3; shift 3
  local rows="$OUT/rows.csv" text="$OUT/rows.txt"
  "$bin" bench --backends wgpu,vulkano "$@" --csv "$rows" > "$text" 2>&1
  grep -E "refused|error" "$text" | sort -u | head -4 | sed "s|^|$label: |"
  grep -E "^(wgpu|vulkano) " "$text" | sed "s|^|$label |"
  [ -s "$csv" ] || sed -n 1p "$rows" | sed 's/^/label,/' > "$csv"
  sed 1d "$rows" | sed "s|^|\"$label\",|" >> "$csv"
}

if [[ " $checks " == *" tuning "* ]]; then
  echo "== tuning: the bench under each GPU tuning"
  : > "$OUT/tuning.csv"
  IFS=';' read -r -a tunings <<< "${TUNINGS:-;--block-width 32;--block-width 128;--workgroup-size 128;--workgroup-size 512;--block-order forward;--block-order alternating}"
  for t in "${tunings[@]}"; do
    # shellcheck disable=SC2086
    t=$(echo "$t" | xargs)
    labelled_bench "$CLOTH" "${t:-defaults}" "$OUT/tuning.csv" --grids 512,1024,2048 --substeps 64 --frames 20 $t | tee -a "$OUT/tuning.txt"
  done
fi

# Runs the command "$@" with this build and with OTHER_CLOTH, by turns, ROUNDS times (default 2),
# each time with `build` the binary and `label` its name and round.
by_turns() {
  for round in $(seq "${ROUNDS:-2}"); do
    for build in "$CLOTH" "$OTHER_CLOTH"; do
      label="$(basename "$build") round $round"
      "$@"
    done
  done
}

# The bench rows of docs/performance.md.
compare_rows() {
  labelled_bench "$build" "$label" "$OUT/compare.csv" --grids 128 --substeps scaled --frames 20 | tee -a "$OUT/compare.txt"
  labelled_bench "$build" "$label" "$OUT/compare.csv" --grids 1024,2048 --substeps 64 --frames 20 | tee -a "$OUT/compare.txt"
}

# The self-collision rows, with the candidate lists' counts.
compare_self_rows() {
  labelled_bench "$build" "$label" "$OUT/compare-self.csv" --effects --scene scenes/self_collision_bench.ron \
    --grids "${SELF_EFFECT_GRIDS:-256,1024}" --frames 10 | tee -a "$OUT/compare-self.txt"
  grep -E "SelfCollision|candidate lists" "$OUT/rows.txt" | sed "s|^|$label |" | tee -a "$OUT/compare-self.txt"
  # Each build's passes on vulkano, where it has `cloth profile`.
  "$build" profile --help > /dev/null 2>&1 || return 0
  local grids=${SELF_EFFECT_GRIDS:-256,1024} n
  for n in ${grids//,/ }; do
    "$build" profile scenes/self_collision_bench.ron --backend vulkano --grid "${n}x$n" --skip 1 --frames 50 2>&1 |
      grep -v '^wrote' | sed "s|^|$label |" >> "$OUT/compare-self-profile.txt"
  done
}

if [[ " $checks " == *" compare "* ]]; then
  echo "== compare: this build against ${OTHER_CLOTH:?OTHER_CLOTH names the other build}"
  : > "$OUT/compare.csv"
  by_turns compare_rows
fi

if [[ " $checks " == *" compare-self "* ]]; then
  echo "== compare-self: the self-collision bench, this build against ${OTHER_CLOTH:?OTHER_CLOTH names the other build}"
  : > "$OUT/compare-self.csv"
  by_turns compare_self_rows
fi

if [[ " $checks " == *" peer "* ]]; then
  echo "== peer: NVIDIA Warp's cloth benchmark and its CuPy and PyTorch versions"
  python3 scripts/peer-cloth.py --grids "${PEER_GRIDS:-128,1024,2048}" --substeps 16,64 --frames 20 \
    > "$OUT/peer-cloth.csv" 2> "$OUT/peer-cloth.txt"
  cat "$OUT/peer-cloth.csv"
fi

if [[ " $checks " == *" study "* ]]; then
  echo "== study accuracy (report: docs/accuracy.md)"
  "$CLOTH" study accuracy --backends cpu,cpu-f64,wgpu,vulkano --no-bisection --report docs/accuracy.md 2>&1 | tee "$OUT/study.txt"
  cp docs/accuracy.md docs/accuracy.csv docs/accuracy.svg docs/accuracy.png "$OUT/"
fi
