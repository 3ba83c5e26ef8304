#!/usr/bin/env bash
# The whole test suite: installs what it needs (the Mitsuba 3 reference venv and the Blender
# (bpy) venv under ~/.cache/evblur, libllvm19 for Mitsuba's LLVM backend when we are root, and
# the LPIPS weights under ~/.cache/evblur/lpips), then runs every test of the workspace, the
# Mitsuba, Blender and real-LPIPS checks included (they must not be skipped here),
# and ends with one summary line "N passed, N failed".
set -euo pipefail
cd "$(dirname "$0")/.."
export EVBLUR_MITSUBA_PYTHON="$(bash tests/mitsuba/setup.sh)"
export EVBLUR_REQUIRE_MITSUBA=1
export EVBLUR_BLENDER_PYTHON="$(bash tests/blender/setup.sh)"
export EVBLUR_REQUIRE_BLENDER=1
bash benchmark/scripts/install_lpips.sh >/dev/null
export EVBLUR_REQUIRE_LPIPS=1
log=$(mktemp)
trap 'rm -f "$log"' EXIT
status=0
cargo test --workspace --locked -- --nocapture 2>&1 | tee "$log" || status=$?
echo
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
     END { printf "evblur: %d passed, %d failed\n", p, f }' "$log"
exit "$status"
