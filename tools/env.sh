# Source me: ROS 2 Jazzy (pip-wheel underlay) + the built ceco workspace.
# Works from any directory and under bash or zsh; never under `set -u`.
_ceco_root=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)
. "$_ceco_root/.venv/local_setup.sh"
. "$_ceco_root/ros_ws/install/setup.bash"
export PATH="$_ceco_root/.venv/bin:$PATH"
unset _ceco_root
