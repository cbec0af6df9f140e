#!/usr/bin/env bash
# The simulated sensor through the command line (ctest cli.sensor): `--sensor random` writes the values it
# drew to sensor_model.txt, the seed decides them; `inspect` finds the hot pixels a recording was given and
# warns when the ON share says the thresholds are asymmetric, and says neither of an ideal recording.
# Usage: tests/sensor.sh EVNERF_BINARY
set -euo pipefail
EV=$1
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_sensor.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
sim() { "$EV" simulate planes --width 48 --height 36 "$@" > /dev/null 2>&1 || fail "simulate $*"; }
sim --out "$work/random" --sensor random --seed 2
sim --out "$work/random_again" --sensor random --seed 2
sim --out "$work/random3" --sensor random --seed 3
for key in threshold_pos threshold_neg mismatch refractory noise_rate hot_pixels hot_rate jitter seed; do
  grep -q "^$key " "$work/random/sensor_model.txt" || fail "sensor_model.txt lacks $key: $(cat "$work/random/sensor_model.txt")"
done
cmp -s "$work/random/sensor_model.txt" "$work/random_again/sensor_model.txt" || fail "the same seed drew another sensor"
cmp -s "$work/random/sensor_model.txt" "$work/random3/sensor_model.txt" && fail "seeds 2 and 3 drew the same sensor"
sim --out "$work/ideal"
grep -q "^threshold_pos 0.25$" "$work/ideal/sensor_model.txt" || fail "the ideal sensor: $(cat "$work/ideal/sensor_model.txt")"
"$EV" inspect "$work/ideal" > "$work/ideal.txt"
grep -q "hot pixels\|asymmetric" "$work/ideal.txt" && fail "inspect of an ideal recording: $(cat "$work/ideal.txt")"
sim --out "$work/hot" --hot-pixels 3 --hot-rate 300
"$EV" inspect "$work/hot" > "$work/hot.txt"
grep -q "^hot pixels    3 suspected" "$work/hot.txt" || fail "inspect did not find the 3 hot pixels: $(cat "$work/hot.txt")"
sim --out "$work/asym" --threshold-pos 0.15 --threshold-neg 0.3
"$EV" inspect "$work/asym" > "$work/asym.txt"
grep -q "thresholds are likely asymmetric" "$work/asym.txt" || fail "inspect did not warn of C+ 0.15, C- 0.3: $(cat "$work/asym.txt")"
echo "sensor: random sensors drawn from the seed and written; inspect finds planted hot pixels and asymmetric thresholds"
