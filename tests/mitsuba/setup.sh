#!/bin/sh
# Idempotent setup of the Mitsuba 3 reference renderer; prints the venv's python path.
# The venv also holds numpy and h5py (file checks) and scikit-image (the PSNR / SSIM reference of
# trainer/src/metrics.rs); it is (re)installed only when one of them is missing or of another
# version. Caches only under ~/.cache/evblur. Installs libllvm19 (for the llvm_ad_rgb variant)
# only when it is missing and we are root; otherwise render.py falls back to scalar_rgb.
set -eu
VENV="${HOME}/.cache/evblur/mitsuba-venv"
PY="${VENV}/bin/python"
if ! "${PY}" -c 'import mitsuba, numpy, h5py, skimage; assert mitsuba.__version__ == "3.9.1" and skimage.__version__ == "0.26.0"' >/dev/null 2>&1; then
    mkdir -p "${HOME}/.cache/evblur"
    python3 -m venv "${VENV}" >&2
    "${VENV}/bin/pip" install --quiet mitsuba==3.9.1 numpy h5py scikit-image==0.26.0 >&2
fi
if ! ls /usr/lib/*/libLLVM.so.19* /usr/lib/*/libLLVM-19.so* >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        (apt-get install -y libllvm19 || (apt-get update && apt-get install -y libllvm19)) >&2 \
            || echo "setup.sh: libllvm19 could not be installed; Mitsuba will use scalar_rgb" >&2
    else
        echo "setup.sh: libllvm19 missing and not root; Mitsuba will use scalar_rgb" >&2
    fi
fi
echo "${PY}"
