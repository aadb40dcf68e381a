#!/usr/bin/env bash
# Runs every shipped example for a fixed number of steps with two `mps` binaries and compares
# the outputs: every VTU array bit for bit, every CSV number (tools/compare_runs.py).
#
#   tools/same_results.sh OLD_MPS NEW_MPS [STEPS]
#
# Used to show that a restructuring changes no result. Exit status 1 if anything differs.
# EXPECT_CHANGED lists columns changed on purpose by a named fix (FILE:COLUMN, space
# separated); they are reported, not counted.
set -euo pipefail
old=$1
new=$2
steps=${3:-150}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
here=$(cd "$(dirname "$0")" && pwd)
status=0
# example, output interval (s) giving a few snapshots within the steps, extra settings.
while read -r name interval extra; do
  [ -z "$name" ] && continue
  label="$name${extra:+ ($extra)}"
  sets=(--set "time.max_steps=$steps" --set "output.interval=$interval" --set output.vtu=true)
  for kv in $extra; do sets+=(--set "$kv"); done
  tag=$(echo "$label" | tr -c 'a-zA-Z0-9_\n' '_')
  "$old" run --example "$name" --out "$work/old_$tag" --quiet "${sets[@]}" >/dev/null 2>&1 || true
  "$new" run --example "$name" --out "$work/new_$tag" --quiet "${sets[@]}" >/dev/null 2>&1 || true
  echo "== $label, $steps steps"
  expect=()
  for e in ${EXPECT_CHANGED:-}; do expect+=(--expect-changed "$e"); done
  if ! python3 "$here/compare_runs.py" "$work/old_$tag" "$work/new_$tag" "${expect[@]}"; then
    status=1
  fi
done <<'CASES'
dam_break 0.01
dam_break 0.01 scheme.name=MPS-HS-GC-DS solver.kind=amg-cg
hydrostatic 0.02
hydrostatic 0.02 scheme.name=MPS-HS-GC
square_patch 0.05
square_patch 0.05 scheme.name=CMPS-HS
two_layer 0.02
settling 0.005
surfacing 0.005 scheme.density_smoothing=true
bench_dam_break 0.005
taylor_green 0.02
rotating_disc 0.05 scheme.surface.detector=scan_region
elliptic_drop 0.001
hydrostatic_3d 0.05
dam_break_3d 0.01 particles.spacing=0.0146
CASES
if [ $status -eq 0 ]; then echo "ALL IDENTICAL"; else echo "DIFFERENCES FOUND"; fi
exit $status
