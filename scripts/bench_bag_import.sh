#!/usr/bin/env bash
# Import speed of `lisfm bag_importer`: a bag of a 2-minute HILTI-like recording (simulated office,
# HILTI 2022 rig: XT-32-like LiDAR 10 Hz, IMU 400 Hz, 5 cameras at CAMERA_RATE Hz, mono8), exported
# with `lisfm bag_exporter --preset hilti2022` uncompressed, lz4 and bz2, then imported; MB/s of bag
# bytes over the importer's wall time (process start to exit, /usr/bin/time -v) and its peak RSS.
#   scripts/bench_bag_import.sh [WORK_DIR] [DURATION_S] [CAMERA_RATE]
#   (defaults: /tmp/lisfm_bench_bag_import, 120, 1)
# The bag is read from the page cache (it was just written; 24 GiB RAM): this measures the importer
# (decoding, de-serialising, PCD / PNG writing), not the disk. Disk: the sequence folder (~2 GB), one
# bag and one imported folder at a time; the bags and imported folders are removed as it goes.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_bag_import}"
DURATION="${2:-120}"
CAMERA_RATE="${3:-1}"
[ -x "$LISFM" ] || { echo "bench_bag_import: build first ($LISFM missing)" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "bench_bag_import: needs /usr/bin/time (Debian package time)" >&2; exit 1; }
mkdir -p "$WORK"
SEQ="$WORK/office"
if [ ! -f "$SEQ/groundtruth.txt" ]; then
  "$LISFM" simulate --scene office --duration "$DURATION" --camera_rate "$CAMERA_RATE" \
    --error_sources none --output_path "$SEQ" --overwrite 1 --quiet
fi

rows=()
for compression in none lz4 bz2; do
  bag="$WORK/office_$compression.bag"
  out="$WORK/imported_$compression"
  rm -rf "$bag" "$out"
  start=$(date +%s%N)
  "$LISFM" bag_exporter --input_path "$SEQ" --output_path "$bag" --preset hilti2022 \
    --compression "$compression" --quiet
  export_s=$(( $(date +%s%N) - start ))
  /usr/bin/time -v -o "$WORK/time_$compression.txt" \
    "$LISFM" bag_importer --input_path "$bag" --output_path "$out" --preset hilti2022 \
    --rig_path "$SEQ/rig.yaml" --quiet 2> "$WORK/import_$compression.log"
  rows+=("$(/usr/bin/python3 - "$compression" "$bag" "$out" "$WORK/time_$compression.txt" "$export_s" <<'PY'
import os, re, sys
compression, bag, out, timefile, export_ns = sys.argv[1:6]
t = open(timefile).read()
wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", t).group(1)
secs = 0.0
for part in wall.split(":"):
    secs = secs * 60 + float(part)
rss_mb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1)) / 1024
cpu = float(re.search(r"User time \(seconds\): (\S+)", t).group(1)) + \
      float(re.search(r"System time \(seconds\): (\S+)", t).group(1))
size = os.path.getsize(bag) / 1e6
outsize = sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(out) for f in fs) / 1e6
scans = sum(1 for l in open(out + "/lidar0/data.csv") if not l.startswith("#"))
images = sum(sum(1 for l in open(os.path.join(out, c, "data.csv")) if not l.startswith("#"))
             for c in sorted(os.listdir(out)) if c.startswith("cam"))
print(f"| {compression} | {size:.0f} | {int(export_ns) * 1e-9:.1f} | {scans} scans, {images} images | "
      f"{secs:.1f} | {cpu:.1f} | {size / secs:.0f} | {outsize / secs:.0f} | {rss_mb:.0f} |")
PY
)")
  rm -rf "$bag" "$out"
done

echo
echo "lisfm bag_importer speed ($(nproc) cores, $(lscpu | sed -n 's/Model name: *//p' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%FT%TZ)); office ${DURATION} s, cameras ${CAMERA_RATE} Hz, preset hilti2022"
echo
echo "| compression | bag MB | export s | content | import wall s | import CPU s | bag MB/s | written MB/s | peak RSS MB |"
echo "|---|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
