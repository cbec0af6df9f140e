#!/usr/bin/env bash
# Installs the Debian packages evnerf needs, only those missing (sudo only when not root).
# Usage: scripts/deps.sh [extra-package ...]
set -euo pipefail
pkgs=(cmake ninja-build g++ libeigen3-dev libxtensor-dev xtl-dev libstb-dev doctest-dev nlohmann-json3-dev libcli11-dev libfmt-dev libhdf5-dev libbz2-dev liblz4-dev libzstd-dev \
  hdf5-filter-plugin-blosc-serial hdf5-filter-plugin libassimp-dev libembree-dev libcpp-httplib-dev "$@")
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  echo "installing: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
