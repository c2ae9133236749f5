#!/usr/bin/env bash
# The main job: set up (idempotent), then run the default distributed optimisation.
# Extra arguments go to `bev-mdo optimize`.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$ROOT/scripts/setup.sh"
. "$ROOT/scripts/env.sh"
cd "$ROOT"
exec bev-mdo optimize config/leaf_nedc.yaml "$@"
