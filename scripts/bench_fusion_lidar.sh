#!/usr/bin/env bash
# `lisfm fusion --mode lidar` on a simulated office run (issue "Targets": LiDAR mode >= 20
# keyframes/s for XT-32-like scans): `lisfm simulate` (SIM_DURATION s, the simulator's default
# XT-32-like LiDAR and its default realistic errors, no cameras) -> `lisfm lio` ->
# `lisfm pose_slam` -> `lisfm fusion --mode lidar` with pose_slam's trajectory, and with the
# ground-truth poses. Scores:
#  - speed: keyframes/s of range-image building + fusion (fusion_summary.json), and wall
#    keyframes/s of the fusion loop with PCD loading;
#  - surface error: distance of every written surfel to scene.ply (bench/fusion_eval.cc, exact
#    point-triangle distance): median, 95th percentile, fraction within 1 cm. pose_slam's poses
#    live in lio's world frame; they are moved into the scene frame by the SE(3) alignment of
#    `lisfm evaluate` (reference_from_estimate) before fusing, which changes nothing but the frame;
#  - memory: surfels written vs scan points in range, bytes per surfel.
# Usage: scripts/bench_fusion_lidar.sh [OUT_DIR]   (default /tmp/lisfm_bench_fusion_lidar;
#        scratch, delete it afterwards). Environment: SIM_DURATION (120), SIM_SEED (1).
# Prints a markdown table for docs/BENCHMARKS.md.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
OUT="${1:-/tmp/lisfm_bench_fusion_lidar}"
SIM_DURATION="${SIM_DURATION:-120}"
SIM_SEED="${SIM_SEED:-1}"
lisfm_build_bench lisfm lisfm_fusion_eval >"$OUT.build.log" 2>&1 || {
  tail -30 "$OUT.build.log"
  echo "error: the build failed (log: $OUT.build.log)" >&2
  exit 1
}
EVAL="$LISFM_BUILD_DIR/bench/lisfm_fusion_eval"
mkdir -p "$OUT"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads;" \
  "start $(date -u +%H:%M:%S) UTC, $(uptime | sed 's/.*load/load/')"

run() {  # run LOG CMD...: runs CMD, keeps its output in LOG, shows it on failure
  local log="$1"
  shift
  "$@" >"$log" 2>&1 || {
    tail -20 "$log"
    echo "error: failed: $*" >&2
    exit 1
  }
}

SEQ="$OUT/seq"
[ -f "$SEQ/rig.yaml" ] || run "$OUT/simulate.log" "$LISFM" simulate --scene office \
  --duration "$SIM_DURATION" --seed "$SIM_SEED" --camera_rate 0 --output_path "$SEQ"
[ -f "$OUT/lio/keyframes/keyframes.csv" ] || run "$OUT/lio.log" "$LISFM" lio --input_path "$SEQ" \
  --output_path "$OUT/lio"
[ -f "$OUT/pose_slam/trajectory.txt" ] || run "$OUT/pose_slam.log" "$LISFM" pose_slam \
  --input_path "$SEQ" --lio_path "$OUT/lio" --output_path "$OUT/pose_slam"

# pose_slam's trajectory in the scene frame: the SE(3) alignment of its keyframe poses.
run "$OUT/evaluate.log" "$LISFM" evaluate --reference_path "$SEQ/groundtruth.txt" \
  --estimate_path "$OUT/pose_slam/keyframes.txt" --output_path "$OUT/evaluate" --overwrite 1
python3 - "$OUT" <<'EOF'
import json, sys
out = sys.argv[1]
a = json.load(open(f"{out}/evaluate/metrics.json"))["reference_from_estimate"]
ax, ay, az, aw = a["rotation_xyzw"]
at = a["translation_m"]
def qmul(p, q):  # (x, y, z, w)
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return (pw * qx + px * qw + py * qz - pz * qy, pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw, pw * qw - px * qx - py * qy - pz * qz)
def rotate(q, v):
    x, y, z, w = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return (x, y, z)
with open(f"{out}/pose_slam/trajectory.txt") as f, open(f"{out}/aligned.txt", "w") as g:
    for line in f:
        if line.startswith("#") or not line.strip():
            g.write(line)
            continue
        v = line.split()
        p = rotate((ax, ay, az, aw), tuple(float(x) for x in v[1:4]))
        q = qmul((ax, ay, az, aw), tuple(float(x) for x in v[4:8]))
        g.write(" ".join([v[0]] + [repr(p[i] + at[i]) for i in range(3)] + [repr(x) for x in q]) + "\n")
EOF

for src in pose_slam groundtruth; do
  if [ "$src" = pose_slam ]; then
    poses=(--pose_source trajectory --trajectory_path "$OUT/aligned.txt")
  else
    poses=(--pose_source groundtruth)
  fi
  echo "fusion ($src poses): $(uptime | sed 's/.*load/load/')"
  run "$OUT/fusion_$src.log" "$LISFM" fusion --mode lidar --input_path "$SEQ" \
    --lio_path "$OUT/lio" "${poses[@]}" --output_path "$OUT/fusion_$src" --overwrite 1
  tail -1 "$OUT/fusion_$src.log"
  run "$OUT/eval_$src.log" "$EVAL" --points_path "$OUT/fusion_$src/surfels.ply" \
    --surface_path "$SEQ/scene.ply" --output_path "$OUT/eval_$src.json"
done
echo "end $(date -u +%H:%M:%S) UTC, $(uptime | sed 's/.*load/load/')"

python3 - "$OUT" <<'EOF'
import json, sys
out = sys.argv[1]
print("| poses | keyframes | range image | fusion kf/s | wall kf/s (with loading) | ms/kf (range image + fusion) "
      "| scan points | surfels | surfels / points | bytes/surfel | surface median / p95 (mm) | within 1 cm |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for src in ("pose_slam", "groundtruth"):
    s = json.load(open(f"{out}/fusion_{src}/fusion_summary.json"))
    e = json.load(open(f"{out}/eval_{src}.json"))
    surf = e["to_surface"]
    med, p95, within = surf["median_m"], surf["p95_m"], surf["within_1cm"]
    ri = s["range_image"]
    ms = s["stage_ms_per_keyframe"]
    print(f"| {src} | {s['keyframes']} | {ri['width']}x{ri['height']} | {s['fusion_keyframes_per_s']:.1f} "
          f"| {s['wall_keyframes_per_s']:.1f} | {ms['preprocess']:.1f} + {ms['fusion']:.1f} "
          f"| {s['scan_points']:,} | {s['surfels']:,} | {100 * s['compression_ratio']:.1f} % "
          f"| {s['bytes_per_surfel']} | {1e3 * med:.1f} / {1e3 * p95:.1f} "
          f"| {100 * within:.1f} % |")
EOF
