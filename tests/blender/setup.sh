#!/bin/sh
# Idempotent setup of Blender as a Python module (bpy, with Cycles and the glTF exporter) for the
# punctual-light check (tests/blender_reference.rs); prints the venv's python path. bpy 4.5 needs
# Python 3.11. Caches only under ~/.cache/evblur (the venv is about 1 GB).
set -eu
VENV="${HOME}/.cache/evblur/bpy-venv"
PY="${VENV}/bin/python"
if ! "${PY}" -c 'import bpy; assert bpy.app.version_string.startswith("4.5.15")' >/dev/null 2>&1; then
    BASE=""
    for p in python3.11 python3; do
        if command -v "$p" >/dev/null 2>&1 && "$p" -c 'import sys; assert sys.version_info[:2] == (3, 11)' 2>/dev/null; then
            BASE="$p"
            break
        fi
    done
    if [ -z "${BASE}" ]; then
        echo "tests/blender/setup.sh: bpy 4.5 needs Python 3.11 (python3.11 or python3); install it" >&2
        exit 1
    fi
    mkdir -p "${HOME}/.cache/evblur"
    rm -rf "${VENV}"
    "${BASE}" -m venv "${VENV}" >&2
    "${VENV}/bin/pip" install --quiet bpy==4.5.15 >&2
fi
echo "${PY}"
