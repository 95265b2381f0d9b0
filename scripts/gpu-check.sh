#!/usr/bin/env bash
# Runs on a borrowed GPU machine (see the device tool): checks both GPU backends on real hardware
# and measures them. Expects release binaries built on the dev machine in devbin/ (cloth, and the
# conformance test binary as devbin/conformance) and the Vulkan loader's .deb files in .gl/.
# Writes its logs and CSVs under $OUT.
set -uo pipefail
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
# The conformance binary looks for the scenes where it was built.
mkdir -p /work && [ -e /work/main ] || ln -sfn "$PWD" /work/main
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$OUT/gpu.txt"
chmod +x devbin/*
echo "== cloth backends"; devbin/cloth backends 2>&1 | tee "$OUT/backends.txt"
echo "== conformance (CI=1: a missing adapter fails)"
CI=1 devbin/conformance --test-threads 4 2>&1 | tee "$OUT/conformance.txt" | grep -E "^test |test result|expected difference|panicked" | tail -60
for b in wgpu vulkano; do
  echo "== cloth run --backend $b"; devbin/cloth run --backend "$b" --json > "$OUT/run-$b.json" 2>&1
  grep -E '"(adapter|nan_count|max_penetration_fraction_of_radius|wall_ms_per_frame|submissions_per_frame|host_waits_per_frame)"' "$OUT/run-$b.json"
done
echo "== bench"
devbin/cloth bench --backends wgpu,vulkano --grids 32,128,512,1024 --substeps 16 --frames 20 --csv "$OUT/bench16.csv" 2>&1 | tee "$OUT/bench16.txt"
devbin/cloth bench --backends wgpu,vulkano --grids 128,1024 --substeps 64 --frames 20 --csv "$OUT/bench64.csv" 2>&1 | tee "$OUT/bench64.txt"
