#!/usr/bin/env bash
# The race against Mitsuba 3 (issue 20, acceptance 2; docs/performance.md): builds photonbox,
# then docs/validation/race.py (its header says what it measures). Needs the references of
# references.sh. About 8 minutes a scene at the default budgets (1, 4, 16, 64 s).
#   docs/validation/race.sh [race.py options, e.g. --scenes cornell --budgets 1 4 16]
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --quiet
python3 docs/validation/race.py "$@"
