#!/usr/bin/env bash
# Installs the Debian packages a make target needs, only those missing.
# Usage: tools/install-deps.sh GROUP...   (groups: build test gl shaders fuzz examples reference plots)
set -eu
pkgs=()
for g in "$@"; do
  case "$g" in
    build)     pkgs+=(gcc g++ make) ;;
    test)      pkgs+=(gcc g++ clang libcmocka-dev valgrind zlib1g-dev) ;;   # zlib: test_loader makes its PNG
    gl)        pkgs+=(libegl-dev libgl-dev libgl1-mesa-dri libegl-mesa0) ;;
    shaders)   pkgs+=(glslang-tools) ;;
    fuzz)      pkgs+=(clang libclang-rt-14-dev) ;;
    examples)  pkgs+=(libglfw3-dev libtinygltf-dev nlohmann-json3-dev libstb-dev xvfb xauth assimp-testmodels) ;;
    reference) pkgs+=(libembree-dev) ;;
    plots)     pkgs+=(gnuplot-nox) ;;
    *) echo "install-deps: unknown group '$g'" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "install-deps: installing ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
