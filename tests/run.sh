#!/usr/bin/env bash
# The whole test suite: installs what it needs (the Mitsuba 3 reference venv under
# ~/.cache/evblur, and libllvm19 for Mitsuba's LLVM backend when we are root), then runs every
# test of the workspace, the Mitsuba reference check included (it must not be skipped here).
set -euo pipefail
cd "$(dirname "$0")/.."
export EVBLUR_MITSUBA_PYTHON="$(bash tests/mitsuba/setup.sh)"
export EVBLUR_REQUIRE_MITSUBA=1
cargo test --workspace --locked -- --nocapture
