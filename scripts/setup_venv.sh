#!/usr/bin/env bash
# Create or update the project venv (.venv/) from nothing, idempotently.
#
#   1. system tools (cmake, g++) through apt-get if missing (Debian 12, as root)
#   2. .venv with Python 3.11, pip >= 24
#   3. pinned ROS 2 Jazzy wheels, scientific stack, HEBO stack (requirements/*.txt)
#   4. build msg_defs/ (interface package air_hockey_msgs) into the venv with CMake
#   5. install air_hockey_agent in editable mode + its ament layout in the venv prefix
#   6. compile the puck prediction's numba kernel (cached; about a second when nothing changed)
#   7. byte-compile air_hockey_agent (only what changed)
#
# Each step records a hash of its inputs in .venv/.stamps/ and is skipped when they have not changed,
# so a second run takes seconds. Set AIR_HOCKEY_SETUP_FORCE=1 to redo every step.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${AIR_HOCKEY_VENV:-$ROOT/.venv}"
STAMPS="$VENV/.stamps"
PY="$VENV/bin/python"
PIP=("$PY" -m pip --disable-pip-version-check --no-input -q)

log() { printf '[setup] %s\n' "$*"; }
die() { printf '[setup] error: %s\n' "$*" >&2; exit 1; }

# hash of files (content + names); missing files hash as empty
inputs_hash() { (cd "$ROOT" && cat "$@" 2>/dev/null; printf '%s\n' "$@") | sha256sum | cut -d' ' -f1; }
stamp_ok() { [[ -z "${AIR_HOCKEY_SETUP_FORCE:-}" && -f "$STAMPS/$1" && "$(cat "$STAMPS/$1")" == "$2" ]]; }
stamp_set() { mkdir -p "$STAMPS"; printf '%s' "$2" > "$STAMPS/$1.tmp" && mv "$STAMPS/$1.tmp" "$STAMPS/$1"; }

find_python() {
  for candidate in "${AIR_HOCKEY_PYTHON:-}" python3.11 python3; do
    [[ -n "$candidate" ]] || continue
    if command -v "$candidate" >/dev/null 2>&1 &&
       "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      command -v "$candidate"; return 0
    fi
  done
  return 1
}

ensure_system_tools() {
  local missing=()
  command -v cmake >/dev/null 2>&1 || missing+=(cmake)
  command -v g++ >/dev/null 2>&1 || missing+=(g++)
  command -v make >/dev/null 2>&1 || missing+=(make)
  [[ ${#missing[@]} -eq 0 ]] && return 0
  log "installing system packages: ${missing[*]}"
  if [[ $(id -u) -eq 0 ]]; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    die "missing ${missing[*]}: install them (sudo apt-get install ${missing[*]}) and run again"
  fi
}

ensure_venv() {
  if [[ ! -x "$PY" ]]; then
    local base; base="$(find_python)" || die "Python 3.11 not found (set AIR_HOCKEY_PYTHON=/path/to/python3.11)"
    log "creating $VENV with $base"
    "$base" -m venv "$VENV"
  fi
  "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' ||
    die "$VENV is not a Python 3.11 venv: remove it and run again"
}

install_requirements() {
  local h; h="$(inputs_hash requirements/*.txt)"
  if stamp_ok requirements "$h"; then log "python dependencies up to date"; return; fi
  log "installing python dependencies (ROS 2 Jazzy wheels, numpy/scipy/pybullet/pin, HEBO stack); first run ~2 min"
  "${PIP[@]}" install -U "pip>=24,<27"
  "${PIP[@]}" install -c "$ROOT/requirements/constraints.txt" \
    -r "$ROOT/requirements/ros.txt" -r "$ROOT/requirements/ros-build.txt" \
    -r "$ROOT/requirements/base.txt" -r "$ROOT/requirements/hebo.txt"
  "${PIP[@]}" install -c "$ROOT/requirements/constraints.txt" --no-deps HEBO==0.3.6
  # ament_index_python finds packages only through AMENT_PREFIX_PATH: default it to the venv prefix.
  local site; site="$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  printf '%s\n' "import os, sys; os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)" \
    > "$site/air_hockey_ament_prefix.pth"
  stamp_set requirements "$h"
}

build_interfaces() {
  local h; h="$(inputs_hash msg_defs/CMakeLists.txt msg_defs/package.xml msg_defs/msg/*.msg msg_defs/srv/*.srv \
    scripts/cmake/drop_missing_wheel_includes.cmake)"
  h="$h-$(cat "$STAMPS/requirements" 2>/dev/null)"
  if stamp_ok interfaces "$h" && "$PY" -c 'import air_hockey_msgs.msg' 2>/dev/null; then
    log "air_hockey_msgs up to date"; return
  fi
  log "building msg_defs/ (air_hockey_msgs) into $VENV"
  local build="$ROOT/build/msg_defs"
  rm -rf "$build"
  cmake -S "$ROOT/msg_defs" -B "$build" -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF \
    -DCMAKE_PROJECT_INCLUDE="$ROOT/scripts/cmake/drop_missing_wheel_includes.cmake" \
    > "$ROOT/build/msg_defs.configure.log" 2>&1 || die "configuring msg_defs failed: see build/msg_defs.configure.log"
  cmake --build "$build" -j2 --target install > "$ROOT/build/msg_defs.build.log" 2>&1 ||
    die "building msg_defs failed: see build/msg_defs.build.log"
  "$PY" -c 'import air_hockey_msgs.msg, air_hockey_msgs.srv' || die "air_hockey_msgs built but does not import"
  stamp_set interfaces "$h"
}

install_package() {
  local h; h="$(inputs_hash setup.py setup.cfg package.xml)-$(cat "$STAMPS/requirements" 2>/dev/null)"
  if stamp_ok package "$h"; then
    log "air_hockey_agent (editable) up to date"
  else
    log "installing air_hockey_agent (editable)"
    "${PIP[@]}" install --no-deps --no-build-isolation -e "$ROOT"
    stamp_set package "$h"
  fi
  # share/air_hockey_agent, ament index marker, lib/air_hockey_agent/<node>: cheap, always refreshed.
  "$PY" -m air_hockey_agent.tools.ament_layout --prefix "$VENV" --source "$ROOT"
}

compile_kernels() {
  # The first process to predict compiles core/puck/prediction_kernel.py (about 15 s here, once per machine and
  # change of the file): here, not in the first game's nodes, which start at once and must be up in
  # config/game.yaml's startup_timeout. Later processes load the cached machine code.
  local start=$SECONDS
  "$PY" -c 'from air_hockey_agent.core.puck.prediction import prepare_prediction; prepare_prediction()' ||
    die "the puck prediction's numba kernel did not compile"
  log "puck prediction kernel ready ($((SECONDS - start)) s)"
}

byte_compile() {
  # Where PYTHONDONTWRITEBYTECODE is set (it is on our CI's and development machines), no process writes
  # __pycache__, so every node and every air-hockey command compiled the package's ~160 modules again:
  # 0.25 s of a failing command's 1.2 s here (10 runs each). Python still reads .pyc files it finds, and
  # ignores one older than its source, so compiling them here is safe and only redoes what changed.
  "$PY" -m compileall -q "$ROOT/air_hockey_agent" || die "byte-compiling air_hockey_agent failed"
}

mkdir -p "$ROOT/build"
ensure_system_tools
ensure_venv
install_requirements
build_interfaces
install_package
compile_kernels
byte_compile
log "ready: $VENV"
