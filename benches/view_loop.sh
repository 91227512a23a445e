#!/usr/bin/env bash
# The viewer's frame-loop benchmark: two mirage binaries (or one binary with two flag sets),
# their runs interleaved round by round, because this machine's speed drifts by 5–15 % over
# minutes. Eight configurations: cornell and Sponza, MTMH and SIR, a still camera and the orbit
# path, at 512×512 with 256 VPLs (8×8 interleave, filter on).
#
#   benches/view_loop.sh OLD_BIN NEW_BIN [ROUNDS]
#
# Environment: OLD_FLAGS / NEW_FLAGS (extra flags of each side, e.g. OLD_FLAGS="--vpls-ahead
# never"), FRAMES_CORNELL (default 120), FRAMES_SPONZA (default 60), SPONZA (default
# ../shared/models/sponza.obj; lit with --add-light; skipped when missing).
#
# Prints one line per run (round, scene, sampler, camera, side, frames/s, ms/frame, ms of VPLs,
# primary, shadow, filter, display), then the means per configuration.
set -euo pipefail
old=${1:?usage: benches/view_loop.sh OLD_BIN NEW_BIN [ROUNDS]}
new=${2:?usage: benches/view_loop.sh OLD_BIN NEW_BIN [ROUNDS]}
rounds=${3:-3}
sponza=${SPONZA:-$(dirname "$0")/../../shared/models/sponza.obj}
scenes="cornell"
[ -f "$sponza" ] && scenes="cornell sponza"
out=$(mktemp)
trap 'rm -f "$out"' EXIT
for round in $(seq "$rounds"); do
  for scene in $scenes; do
    for sampler in mtmh sir; do
      for camera in still orbit; do
        for side in OLD NEW; do
          if [ "$scene" = cornell ]; then
            args=(--frames "${FRAMES_CORNELL:-120}")
          else
            args=("$sponza" --add-light --frames "${FRAMES_SPONZA:-60}")
          fi
          [ "$camera" = orbit ] && args+=(--camera-path orbit)
          if [ "$side" = OLD ]; then bin=$old; flags=${OLD_FLAGS:-}; else bin=$new; flags=${NEW_FLAGS:-}; fi
          # shellcheck disable=SC2086 # the flag strings are meant to split
          line=$("$bin" view "${args[@]}" --headless --width 512 --height 512 --vpls 256 \
            --vpl-sampler "$sampler" $flags 2>&1 | tail -1)
          # (The shadow time may carry "(compensation N)": the clamp compensation's part of it.)
          nums=$(echo "$line" | sed -E 's/.*: ([0-9.]+) frames\/s \(([0-9.]+) ms\/frame: VPLs ([0-9.]+), primary ([0-9.]+), shadow ([0-9.]+)( \(compensation [0-9.]+\))?, filter ([0-9.]+), display ([0-9.]+).*/\1 \2 \3 \4 \5 \7 \8/')
          echo "$round $scene $sampler $camera $side $nums" | tee -a "$out"
        done
      done
    done
  done
done
echo
echo "means over $rounds rounds: scene sampler camera side frames/s ms/frame VPLs primary shadow filter display"
awk '{k = $2 " " $3 " " $4 " " $5; n[k]++; for (i = 6; i <= 12; i++) s[k, i] += $i}
     END {for (k in n) {printf "%s", k; for (i = 6; i <= 12; i++) printf " %.2f", s[k, i] / n[k]; printf "\n"}}' \
  "$out" | sort
