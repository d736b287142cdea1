#!/usr/bin/env bash
# Installs the Debian 12 packages mosaicloc builds, tests and runs with. Idempotent and
# quick when everything is present; needs root (or sudo) only when something is missing.
set -euo pipefail

PACKAGES=(
  # toolchain
  cmake ninja-build g++ pkg-config
  # libraries (design.md section 2)
  libvisp-dev libopencv-dev libeigen3-dev libceres-dev libsuitesparse-dev libmodbus-dev libv4l-dev
  libsqlite3-dev zlib1g-dev libpng-dev libdeflate-dev libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev python3
  # ViSP's own test images: the calibration tests' circle grid, the renderer's reference warps
  visp-images-data
  # independent Modbus peers for the PLC tests, and linked pseudo-terminals for Modbus RTU
  python3-pymodbus python3-serial python3-serial-asyncio mbpoll socat
  # a real browser for the report page and the console
  chromium
  # the console: an HTTP server, and the map viewer it serves from the Debian package
  libcpp-httplib-dev libjs-leaflet
  # the console's tests and tutorial ask it as any HTTP client would
  curl
)

missing=()
for package in "${PACKAGES[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$package" 2>/dev/null || true)
  [ "$status" = "installed" ] || missing+=("$package")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: run as root or install sudo" >&2; exit 1; }
  SUDO=sudo
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done" >&2
