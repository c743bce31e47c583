#!/usr/bin/env bash
# One command: install what is missing, build, check formatting, run the whole test suite.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
"$GEN4D_ROOT/cmake/install-deps.sh"
gen4d_build
cmake --build "$GEN4D_BUILD" --target check-format
cd "$GEN4D_BUILD"
ctest --output-on-failure -j "$GEN4D_JOBS" --timeout 900
