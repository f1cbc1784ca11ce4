#!/usr/bin/env bash
# `lisfm fusion` side by side with Open3D on the same RGB-D frames (issue "Targets"):
#  - 7-Scenes subset (../shared/data/rgbd_7scenes_subset, 200 real Kinect frames, the data
#    set's KinectFusion poses as reference);
#  - a simulated office RGB-D sequence (`lisfm simulate --rgbd 1`, SIM_DURATION s at SIM_RATE
#    Hz, clean: --error_sources none, depth noise of a structured-light sensor), exact ground
#    truth and the scene mesh.
# Per data set: `lisfm fusion` with ICP poses and with the data set's poses; Open3D's
# ComputeRGBDOdometry (hybrid term, frame to frame) and ScalableTSDFVolume with the data set's
# poses (bench/fusion_open3d.cc), all at the same downsample factor (2: 320x240) on frames read
# with core/io/rgbd_io. Scores: ATE (`lisfm evaluate`, SE(3) alignment) against the data set's
# poses; distance of the model's points to Open3D's mesh vertices and, for simulated data, to
# scene.ply (bench/fusion_eval.cc); points, compression ratio (points / input pixels), bytes
# per point; tracking + fusion time per frame and the speed ratio.
# Usage: scripts/bench_fusion.sh [OUT_DIR]   (default /tmp/lisfm_bench_fusion; scratch, delete
#        it afterwards). Environment: SIM_DURATION (60), SIM_RATE (30), SIM_SEED (1),
#        FUSION_DATASETS ("7scenes sim_office": the data sets to run).
# Prints a markdown table for docs/BENCHMARKS.md. Exits 1 with a message when `lisfm fusion`
# is not built.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
OUT="${1:-/tmp/lisfm_bench_fusion}"
SIM_DURATION="${SIM_DURATION:-60}"
SIM_RATE="${SIM_RATE:-30}"
SIM_SEED="${SIM_SEED:-1}"
FUSION_DATASETS="${FUSION_DATASETS:-7scenes sim_office}"
lisfm_build_bench lisfm lisfm_fusion_open3d lisfm_fusion_eval >"$OUT.build.log" 2>&1 || {
  tail -30 "$OUT.build.log"
  echo "error: the build failed (log: $OUT.build.log)" >&2
  exit 1
}
if ! "$LISFM" fusion -h >/dev/null 2>&1; then
  echo "error: this lisfm has no 'fusion' command ('$LISFM fusion -h' fails): build the branch" \
    "that adds apps/fusion_command.cc first" >&2
  exit 1
fi
O3D="$LISFM_BUILD_DIR/bench/lisfm_fusion_open3d"
EVAL="$LISFM_BUILD_DIR/bench/lisfm_fusion_eval"
# Open3D's OpenMP workers otherwise spin after each parallel region and take the other core
# (as in scripts/bench_icp.sh); set OMP_WAIT_POLICY to override.
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-passive}"
mkdir -p "$OUT"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads;" \
  "start $(date -u +%H:%M:%S) UTC, $(uptime | sed 's/.*load/load/'); OMP_WAIT_POLICY=$OMP_WAIT_POLICY"

now() { date +%s.%N; }

# run_dataset NAME SEQ [SURFACE_PLY]
run_dataset() {
  local name="$1" seq="$2" surface="${3:-}"
  local dir="$OUT/$name"
  mkdir -p "$dir"
  echo "== $name: $seq" >&2
  for src in icp groundtruth; do
    local t0
    t0=$(now)
    "$LISFM" fusion --input_path "$seq" --output_path "$dir/ours_$src" --pose_source "$src" \
      --overwrite 1 >"$dir/ours_$src.log" 2>&1 || {
      tail -20 "$dir/ours_$src.log"
      echo "error: lisfm fusion --pose_source $src failed on $seq (log: $dir/ours_$src.log)" >&2
      exit 1
    }
    echo "$(now) - $t0" | bc >"$dir/ours_$src.wall_s"
  done
  "$O3D" --input_path "$seq" --output_path "$dir/open3d" >"$dir/open3d.log" 2>&1 || {
    tail -20 "$dir/open3d.log"
    echo "error: lisfm_fusion_open3d failed on $seq (log: $dir/open3d.log)" >&2
    exit 1
  }
  for traj in ours_icp/trajectory.txt open3d/trajectory.txt; do
    local tag="${traj%%/*}"
    "$LISFM" evaluate --reference_path "$dir/open3d/groundtruth.txt" --estimate_path \
      "$dir/$traj" --alignment se3 --output_path "$dir/evaluate_$tag" --overwrite 1 \
      >"$dir/evaluate_$tag.log" 2>&1 || {
      tail -20 "$dir/evaluate_$tag.log"
      echo "error: lisfm evaluate failed on $dir/$traj" >&2
      exit 1
    }
  done
  local surface_args=()
  [[ -n "$surface" ]] && surface_args=(--surface_path "$surface")
  for src in icp groundtruth; do
    "$EVAL" --points_path "$dir/ours_$src/surfels.ply" --vertices_path "$dir/open3d/mesh.ply" \
      "${surface_args[@]}" --output_path "$dir/eval_ours_$src.json" >"$dir/eval_ours_$src.log"
  done
  if [[ -n "$surface" ]]; then
    "$EVAL" --points_path "$dir/open3d/mesh.ply" --surface_path "$surface" \
      --output_path "$dir/eval_open3d.json" >"$dir/eval_open3d.log"
  fi
}

SEVEN="$LISFM_SHARED_DATA/rgbd_7scenes_subset"
if [[ " $FUSION_DATASETS " != *" 7scenes "* ]]; then
  :
elif [[ -d "$SEVEN" ]]; then
  run_dataset 7scenes "$SEVEN"
else
  echo "warning: $SEVEN is missing; skipping the 7-Scenes rows" >&2
fi

SIM="$OUT/sim_office_${SIM_DURATION}s_${SIM_RATE}hz"
if [[ " $FUSION_DATASETS " != *" sim_office "* ]]; then
  :
elif [[ ! -f "$SIM/rgbd0/data.csv" ]]; then
  t0=$(now)
  "$LISFM" simulate --scene office --duration "$SIM_DURATION" --seed "$SIM_SEED" --rgbd 1 \
    --rgbd_rate "$SIM_RATE" --lidars none --camera_rate 0 --error_sources none \
    --output_path "$SIM" --overwrite 1 >"$SIM.log" 2>&1 || {
    tail -20 "$SIM.log"
    echo "error: lisfm simulate failed (log: $SIM.log)" >&2
    exit 1
  }
  echo "simulated $SIM in $(echo "$(now) - $t0" | bc | xargs printf '%.0f') s" >&2
fi
if [[ " $FUSION_DATASETS " == *" sim_office "* ]]; then
  run_dataset sim_office "$SIM" "$SIM/scene.ply"
fi

echo "end $(date -u +%H:%M:%S) UTC, $(uptime | sed 's/.*load/load/')"
python3 - "$OUT" <<'EOF'
import json, os, sys

out = sys.argv[1]

def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None

def mm(stats, key="median_m"):
    return f"{1e3 * stats[key]:.1f}" if stats and stats.get("count") else "—"

def ate_cm(dir_, tag):
    m = load(os.path.join(dir_, f"evaluate_{tag}", "metrics.json"))
    return f"{1e2 * m['ate']['translation_m']['rmse']:.2f}" if m else "—"

rows = []
speed = []
for name, label in (("7scenes", "7-Scenes subset"), ("sim_office", "simulated office")):
    d = os.path.join(out, name)
    o3d = load(os.path.join(d, "open3d", "open3d_summary.json"))
    if not o3d:
        continue
    for src, pose_label in (("icp", "ICP"), ("groundtruth", "given")):
        s = load(os.path.join(d, f"ours_{src}", "fusion_summary.json")) or {}
        e = load(os.path.join(d, f"eval_ours_{src}.json")) or {}
        fps = s.get("tracking_fusion_frames_per_s", 0)
        ms = 1e3 / fps if fps > 0 else 0.0
        rows.append([
            label, f"lisfm fusion, {pose_label} poses", f"{s.get('frames', '?')} @ "
            f"{s.get('width', '?')}x{s.get('height', '?')}",
            ate_cm(d, "ours_icp") if src == "icp" else "(given)",
            f"{mm(e.get('to_vertices'))} / {mm(e.get('to_vertices'), 'p95_m')}",
            f"{mm(e.get('to_surface'))} / {mm(e.get('to_surface'), 'p95_m')}",
            f"{s.get('surfels', 0):,}", f"{100 * s.get('compression_ratio', 0):.2f} %",
            str(s.get("bytes_per_surfel", "—")), f"{ms:.1f}",
            f"{s.get('tracking_fusion_frames_per_s', 0):.1f}"])
        if src == "icp":
            ours_icp_fps = s.get("tracking_fusion_frames_per_s", 0)
    e = load(os.path.join(d, "eval_open3d.json")) or {}
    pixels = o3d["frames"] * o3d["width"] * o3d["height"]
    rows.append([
        label, "Open3D odometry (hybrid) + ScalableTSDFVolume (given poses)",
        f"{o3d['frames']} @ {o3d['width']}x{o3d['height']}", ate_cm(d, "open3d"), "(reference)",
        f"{mm(e.get('to_surface'))} / {mm(e.get('to_surface'), 'p95_m')}",
        f"{o3d['mesh_vertices']:,} vertices", f"{100 * o3d['mesh_vertices'] / pixels:.2f} %", "—",
        f"{o3d['odometry_plus_integration_ms_per_frame']:.1f}", f"{o3d['frames_per_s']:.1f}"])
    if name == "7scenes":
        rows.append([label, "write-up (Python), given poses", "200 @ 320x240", "—", "—", "—",
                     "1,362,157", "8.87 %", "—", "—", "—"])
        rows.append([label, "write-up (Python), ICP poses", "200 @ 320x240", "—", "—", "—",
                     "807,812", "5.26 %", "—", "—", "—"])
    if o3d["frames_per_s"] > 0:
        speed.append(f"{label}: lisfm (ICP poses) {ours_icp_fps:.1f} frames/s vs Open3D "
                     f"{o3d['frames_per_s']:.1f} frames/s = {ours_icp_fps / o3d['frames_per_s']:.1f}x")

print()
print("| data | method | frames | ATE rmse (cm) | to Open3D mesh vertices median / p95 (mm) "
      "| to scene mesh median / p95 (mm) | points | compression | bytes/point "
      "| tracking + fusion (ms/frame) | frames/s |")
print("|" + "---|" * 11)
for r in rows:
    print("| " + " | ".join(r) + " |")
print()
for line in speed:
    print(f"- speed {line}")
EOF
