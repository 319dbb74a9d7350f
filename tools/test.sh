#!/usr/bin/env bash
# Run the whole ceco test suite: sets up (idempotent; see tools/setup.sh),
# sources the workspace, runs pytest. Extra arguments go to pytest.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
bash tools/setup.sh
set +u
# shellcheck disable=SC1091
. tools/env.sh
set -u
exec python -m pytest "$@"
