#!/bin/sh
# Idempotent build of esim_py (ESIM's C++ event simulator with Python bindings, from
# uzh-rpg/rpg_vid2e, GPL-3.0, so not copied here) into ~/.cache/evblur/esim-venv, for the
# speed comparison of `evsim bench esim`; prints the venv's python path.
#
#   tests/esim/setup.sh PATH/TO/rpg_vid2e/esim_py
#
# The source is not on a package registry: clone https://github.com/uzh-rpg/rpg_vid2e and pass
# its esim_py folder. Needs a C++ compiler, CMake, OpenCV, Eigen and Boost.Filesystem; as root on
# Debian/Ubuntu the script installs them (apt-get) when missing.
set -eu
VENV="${HOME}/.cache/evblur/esim-venv"
PY="${VENV}/bin/python"
if "${PY}" -c 'import esim_py' >/dev/null 2>&1; then
    echo "${PY}"
    exit 0
fi
SRC="${1:-}"
if [ -z "${SRC}" ] || [ ! -f "${SRC}/src/esim.cpp" ] || [ ! -f "${SRC}/CMakeLists.txt" ]; then
    echo "tests/esim/setup.sh: give the esim_py folder of a clone of https://github.com/uzh-rpg/rpg_vid2e" \
         "(it holds src/esim.cpp and CMakeLists.txt); got '${SRC}'" >&2
    exit 1
fi
if ! dpkg -s libopencv-dev libeigen3-dev libboost-filesystem-dev cmake >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq g++ cmake libopencv-dev libeigen3-dev \
            libboost-filesystem-dev libboost-system-dev python3-venv python3-dev >&2
    else
        echo "tests/esim/setup.sh: install cmake, OpenCV, Eigen 3 and Boost.Filesystem development files" >&2
        exit 1
    fi
fi
mkdir -p "${HOME}/.cache/evblur"
rm -rf "${VENV}"
python3 -m venv "${VENV}" >&2
"${VENV}/bin/pip" install --quiet numpy 'pybind11[global]' setuptools wheel >&2
BUILD="$(mktemp -d)"
trap 'rm -rf "${BUILD}"' EXIT
cp -r "${SRC}/." "${BUILD}/"
# esim_py's CMakeLists finds pybind11 by its CMake package; point it at the venv's
(cd "${BUILD}" && rm -rf build bin && \
    CMAKE_PREFIX_PATH="$("${PY}" -c 'import pybind11; print(pybind11.get_cmake_dir())')" \
    "${PY}" -m pip install --quiet --no-build-isolation . >&2)
"${PY}" -c 'import esim_py' >&2
echo "${PY}"
