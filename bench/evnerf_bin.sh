# Sourced by the quality scripts (from the repository's root): EV, the evnerf binary they run: EVNERF where
# given (it must be executable), else $BUILD/examples/evnerf, built there in Release when missing (without
# AVX-512 where the script sets NO512=ON).
BUILD=${BUILD:-build}
EV="${EVNERF:-$BUILD/examples/evnerf}"
[ -z "${EVNERF:-}" ] || [ -x "$EV" ] || { echo "$(basename "$0" .sh): EVNERF=$EV is not an executable" >&2; exit 2; }
[ -x "$EV" ] || { cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_NO_AVX512="${NO512:-OFF}" >/dev/null; cmake --build "$BUILD" -j"$(nproc)" --target evnerf_cli; }
