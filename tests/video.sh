#!/usr/bin/env bash
# render --video: a small scene trained briefly, rendered with --video, and its two MP4 files read by
# ffprobe: the frame count (every boundary view, every novel view), the size (intensity beside depth, made
# even), the rate. Without ffmpeg on the PATH: a clear message, the PNG frames as always, no video and no
# half-written file. Skipped (exit 77) where ffmpeg is not installed. ctest runs this as cli.video.
# Usage: tests/video.sh EVNERF_BINARY
set -euo pipefail
EV=$(realpath "$1")
command -v ffmpeg > /dev/null && command -v ffprobe > /dev/null || { echo "video: ffmpeg is not installed, skipped"; exit 77; }
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_video.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$EV" simulate object --out "$work/rec" --width 48 --height 35 > /dev/null 2>&1
"$EV" train "$work/rec" --out "$work/run" --iterations 30 --pixels 256 --quiet > "$work/train.log" 2>&1 || fail "train: $(tail -3 "$work/train.log")"
"$EV" render "$work/run/model.ckpt" --out "$work/render" --novel 7 --video --fps 12 > "$work/render.log" 2>&1 ||
  fail "render --video: $(cat "$work/render.log")"
boundaries=$(ls "$work/render"/boundary_*_depth.png | wc -l)
[ "$boundaries" -ge 2 ] || fail "no boundary views"
probe() { ffprobe -v error -select_streams v:0 -count_frames -show_entries stream=codec_name,width,height,r_frame_rate,nb_read_frames,pix_fmt \
  -of default=noprint_wrappers=1 "$1"; }
for f in recorded:$boundaries novel:7; do
  name=${f%%:*} want=${f#*:}
  [ -f "$work/render/$name.mp4" ] || fail "no $name.mp4: $(cat "$work/render.log")"
  info=$(probe "$work/render/$name.mp4")
  for line in codec_name=h264 width=98 height=36 r_frame_rate=12/1 pix_fmt=yuv420p "nb_read_frames=$want"; do
    grep -qx "$line" <<<"$info" || fail "$name.mp4: expected $line, ffprobe says: $(tr '\n' ' ' <<<"$info")"
  done
done
ls "$work/render"/*.tmp.mp4 > /dev/null 2>&1 && fail "a temporary video was left behind"
# Without ffmpeg: the frames, a message, no video.
PATH=/nonexistent "$EV" render "$work/run/model.ckpt" --out "$work/plain" --novel 2 --video > "$work/plain.log" 2>&1 ||
  fail "render --video without ffmpeg failed: $(cat "$work/plain.log")"
grep -q "needs ffmpeg" "$work/plain.log" || fail "no message without ffmpeg: $(cat "$work/plain.log")"
[ -f "$work/plain/novel_0001.png" ] || fail "no PNG frames without ffmpeg"
ls "$work/plain"/*.mp4 > /dev/null 2>&1 && fail "a video without ffmpeg"
echo "video: recorded.mp4 ($boundaries frames) and novel.mp4 (7) read by ffprobe; without ffmpeg the frames and a message"
