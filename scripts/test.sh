#!/usr/bin/env bash
# Builds evnerf and runs the whole test suite (doctest via ctest, failtests, the installed-package
# consumer). Installs missing Debian packages first.
set -euo pipefail
cd "$(dirname "$0")/.."
# python3-rosbag and friends write the ROS bag of the cli.rosbag test (an independent writer).
# python3-flatbuffers, python3-lz4 and python3-zstandard write the AEDAT4 files of the cli.aedat4 test.
# pybind11-dev, python3-dev, numpy, pytest, matplotlib and venv: the Python module, its tests and its example.
# libopenmpi-dev and openmpi-bin: the tool's data-parallel training (mpirun), tested by mpi.train.
# clang-format-14: docs.format checks every C++ file against .clang-format.
# ffmpeg: render --video's MP4 files, which the cli.video test reads back with ffprobe.
# chromium and chromium-driver: the cli.view test opens evnerf view's page in headless Chromium.
# ccache: a compile repeated with the same source and flags (the Python module that python.pip builds
# through `pip install .`, a rebuild after a checkout) comes from its cache.
scripts/deps.sh ccache ffmpeg chromium chromium-driver clang-format-14 python3-rosbag python3-genpy python3-sensor-msgs python3-geometry-msgs python3-nav-msgs python3-pil \
  python3-flatbuffers python3-lz4 python3-zstandard assimp-testmodels \
  pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib python3-venv libopenmpi-dev openmpi-bin
BUILD=${BUILD:-build}
# The Python module is built for Debian's interpreter (/usr/bin/python3), whose numpy and pytest the tests use.
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_BUILD_TESTS=ON -DEVNERF_BUILD_EXAMPLES=ON \
  -DEVNERF_PYTHON=ON -DPython_EXECUTABLE=/usr/bin/python3 -DEVNERF_MPI=ON -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
  -DCMAKE_INSTALL_PREFIX="$PWD/$BUILD/install" >/dev/null
cmake --build "$BUILD" -j"$(nproc)"
# Install, then build a separate project against the installed package with find_package(evnerf).
cmake --install "$BUILD" >/dev/null
cmake -S tests/consumer -B "$BUILD/consumer" -G Ninja -DCMAKE_PREFIX_PATH="$PWD/$BUILD/install" >/dev/null
cmake --build "$BUILD/consumer" >/dev/null
"$BUILD/consumer/consumer"
cd "$BUILD" && ctest --output-on-failure -j"$(nproc)" --timeout 900
