#!/usr/bin/env bash
# Rebuilds this folder's summary.json and summary.md: all four planners under the published
# profile and THP and GREEDY under the default profile, on the 66 real plans x 3 paired random
# starts (seeds 1-3). About an hour on 2 cores. The raw rows, per-plan plots and CSV files are
# written to a scratch folder (kept, and named at the end), since they are too large to commit.
#
#   results/real-plans-profiles/regenerate.sh [SCRATCH_DIR]
#
# Uses target/release/tensorscout (built if missing), or $TENSORSCOUT if set.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
cd "$root"
bin="${TENSORSCOUT:-$root/target/release/tensorscout}"
if [[ -z "${TENSORSCOUT:-}" ]]; then
    cargo build --release --locked --bin tensorscout
fi
scratch="${1:-$(mktemp -d -t tensorscout-real-plans-XXXXXX)}"
jobs="$(nproc)"
"$bin" bench --scenes scenes/floorplans --planners thp,tensor,nbv,greedy --profile published \
    --seeds 3 --jobs "$jobs" --out "$scratch/published" --resume --quiet
"$bin" bench --scenes scenes/floorplans --planners thp,greedy \
    --seeds 3 --jobs "$jobs" --out "$scratch/default" --resume --quiet
"$bin" bench merge "$scratch/published" "$scratch/default" --out "$scratch/both" --force
cp "$scratch/both/summary.json" "$scratch/both/summary.md" "$here/"
echo "summary.json and summary.md rebuilt in $here; raw rows and plots in $scratch/both"
