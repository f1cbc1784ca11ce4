#!/usr/bin/env bash
# Error-source ablation of `lisfm simulate` seen through `lisfm lio`: the five-minute construction
# site (--scene site, LiDAR only: --camera_rate 0) simulated with no error source, with each
# source that acts on the LiDAR / IMU data alone (calibration, imu, lidar, dynamics) and with all
# of them (the default), then `lisfm lio` with its default options and `lisfm evaluate` against
# groundtruth.txt. Per run: ATE rmse and max (SE(3) alignment, the evaluate default) and the drift
# per 100 m: the mean over 100 m path segments (one starting every second) of the translation
# error of the segment's relative pose, as a percentage of its length (KITTI style).
#   scripts/bench_sim_ablation.sh [WORK_DIR] [DURATION_S] [SEEDS] [SOURCES]
#   (defaults: /tmp/lisfm_bench_sim_ablation, 300, "4 5 6", "none calibration imu lidar dynamics all")
# Rows are appended to WORK_DIR/ablation.md as each run ends, so a partial run still gives numbers;
# a run whose row is already there is skipped. Sequences are deleted after their run (~4 GB each).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_sim_ablation}"
DURATION="${2:-300}"
SEEDS="${3:-4 5 6}"
SOURCES="${4:-none calibration imu lidar dynamics all}"
[ -x "$LISFM" ] || { echo "bench_sim_ablation: build first ($LISFM missing)" >&2; exit 1; }
mkdir -p "$WORK"
TABLE="$WORK/ablation.md"
if [ ! -f "$TABLE" ]; then
  {
    echo "site ${DURATION} s, LiDAR only; $(nproc) cores, $(lscpu | sed -n 's/Model name: *//p' | head -1)"
    echo
    echo "| seed | error sources | scans used | ATE rmse cm | ATE max cm | drift % per 100 m | path m |"
    echo "|---|---|---|---|---|---|---|"
  } > "$TABLE"
fi

for seed in $SEEDS; do
  for sources in $SOURCES; do
    if grep -q "^| $seed | $sources |" "$TABLE"; then continue; fi
    seq="$WORK/site_s${seed}_${sources}"
    out="$WORK/lio_s${seed}_${sources}"
    "$LISFM" simulate --scene site --duration "$DURATION" --camera_rate 0 --lidars spinning \
      --seed "$seed" --error_sources "$sources" --output_path "$seq" --overwrite 1 --quiet
    "$LISFM" lio --input_path "$seq" --output_path "$out" --write_keyframes 0 --overwrite 1 --quiet
    cp "$seq/groundtruth.txt" "$out/groundtruth.txt"
    rm -rf "$seq"
    "$LISFM" evaluate --reference_path "$out/groundtruth.txt" \
      --estimate_path "$out/trajectory.txt" --max_dt 0.006 --output_path "$out/eval" \
      --overwrite 1 --quiet > /dev/null
    /usr/bin/python3 - "$seed" "$sources" "$out" >> "$TABLE" <<'PY'
import bisect, csv, json, math, sys
seed, sources, out = sys.argv[1], sys.argv[2], sys.argv[3]

def read_tum(path):
    poses = []
    for line in open(path):
        f = line.split()
        if not f or f[0].startswith("#"):
            continue
        poses.append((float(f[0]), [float(v) for v in f[1:4]], [float(v) for v in f[4:8]]))
    return poses

def rotate_inverse(q, v):  # R(q)^T v, q = (x, y, z, w)
    x, y, z, w = q
    x, y, z = -x, -y, -z
    # v' = v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
    c1 = (y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0])
    c2 = (y * c1[2] - z * c1[1], z * c1[0] - x * c1[2], x * c1[1] - y * c1[0])
    return [v[i] + 2 * w * c1[i] + 2 * c2[i] for i in range(3)]

gt = read_tum(out + "/groundtruth.txt")
est = read_tum(out + "/trajectory.txt")
gt_t = [p[0] for p in gt]
pairs = []
for t, p, q in est:
    i = bisect.bisect_left(gt_t, t)
    best = min((j for j in (i - 1, i) if 0 <= j < len(gt)), key=lambda j: abs(gt_t[j] - t))
    if abs(gt_t[best] - t) <= 0.006:
        pairs.append((gt[best], (t, p, q)))
length = [0.0]
for k in range(1, len(pairs)):
    length.append(length[-1] + math.dist(pairs[k][0][1], pairs[k - 1][0][1]))
errors = []
next_start = -1e18
for i in range(len(pairs)):
    if pairs[i][0][0] < next_start:
        continue
    next_start = pairs[i][0][0] + 1.0
    j = bisect.bisect_left(length, length[i] + 100.0)
    if j >= len(pairs):
        break
    (_, gi, qi), (_, gj, _) = pairs[i][0], pairs[j][0]
    (_, ei, eqi), (_, ej, _) = pairs[i][1], pairs[j][1]
    d_ref = rotate_inverse(qi, [gj[k] - gi[k] for k in range(3)])
    d_est = rotate_inverse(eqi, [ej[k] - ei[k] for k in range(3)])
    errors.append(math.dist(d_ref, d_est) / (length[j] - length[i]))
drift = 100 * sum(errors) / len(errors) if errors else float("nan")
rows = [r for r in csv.reader(open(out + "/scans.csv")) if not r[0].startswith("#")]
used = sum(1 for r in rows if r[1] == "1")
ate = json.load(open(out + "/eval/metrics.json"))["ate"]["translation_m"]
print(f"| {seed} | {sources} | {used}/{len(rows)} | {ate['rmse'] * 100:.2f} | "
      f"{ate['max'] * 100:.2f} | {drift:.3f} | {length[-1]:.0f} |")
PY
    tail -1 "$TABLE"
  done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$TABLE"
cat "$TABLE"
