#!/usr/bin/env bash
# The long checks CI leaves out to stay within its time: the tests labelled `nightly` (the
# small blind and library diagnoses, the ElastoGen frequency test and the 1-rank runs of two
# validation twins: tests/CMakeLists.txt), then the hardening step with long fuzz runs
# (FUZZ_SECONDS per target, default 1800, one at a time). Run it nightly or before a release;
# it installs and builds like run-tests.sh.
#   jobs/local/run-nightly.sh
set -euo pipefail
# shellcheck source=SCRIPTDIR/../env.sh
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
"$GEN4D_ROOT/cmake/install-deps.sh"
gen4d_build
(cd "$GEN4D_BUILD" && ctest --output-on-failure -j "$GEN4D_JOBS" --timeout 1800 -L nightly)
FUZZ_SECONDS="${FUZZ_SECONDS:-1800}" FUZZ_JOBS="${FUZZ_JOBS:-1}" \
  "$GEN4D_ROOT/jobs/local/run-hardening.sh"
