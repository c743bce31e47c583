#!/usr/bin/env bash
# One command: install what is missing, build, check formatting, run the whole test suite
# (the `nightly` label aside: jobs/local/run-nightly.sh), then the hardening step: the
# ASan+UBSan build of the serial unit suites and a smoke run of every fuzz target
# (jobs/local/run-hardening.sh; FUZZ_SECONDS per target).
set -euo pipefail
# shellcheck source=SCRIPTDIR/../env.sh
source "$(dirname "${BASH_SOURCE[0]}")/../env.sh"
"$GEN4D_ROOT/cmake/install-deps.sh"
gen4d_build
cmake --build "$GEN4D_BUILD" --target check-format
(cd "$GEN4D_BUILD" && ctest --output-on-failure -j "$GEN4D_JOBS" --timeout 900 -LE nightly)
"$GEN4D_ROOT/jobs/local/run-hardening.sh"
