#!/usr/bin/env bash
# FAST-LIO2 side by side with `lisfm lio` on the SAME ROS1 bag (issue 23, Deliver 3).
#   scripts/bench_fastlio.sh [WORK_DIR] [DURATION_S]   (defaults: /tmp/lisfm_bench_fastlio, 120)
#
# 1. Builds the unmodified FAST-LIO2 (../shared/peers/fast_lio, hku-mars/FAST_LIO 7cc4175) with
#    ../shared/peers/build_fastlio.sh in a scratch catkin workspace under $PEERS (default
#    $LISFM_BUILD_DIR/peers; Debian ROS1 packages, installed by that script). It is never a
#    dependency of lisfm. If it cannot be built here, this script says so and exits 3.
# 2. Simulates the sequences of scripts/bench_lio.sh (no cameras, --error_sources none): the office
#    driven by the real HILTI 2022 exp04 handheld motion and the two-storey staircase.
# 3. Exports each to a bag in the layout FAST-LIO2's lidar_type 2 reads:
#    `lisfm bag_exporter --preset velodyne` (PointCloud2 x y z intensity float32, `time` float32 s
#    since header.stamp, ring uint16; points in time order; /imu/data sensor_msgs/Imu), and writes
#    FAST-LIO2's YAML (upstream config/velodyne.yaml with the rig's extrinsic, scan_line,
#    timestamp_unit 0 and blind = lisfm lio's --Lio.min_range 0.5 m; FASTLIO_BLIND overrides).
# 4. FAST-LIO2 plays the bag lock-step (build/peers/fastlio/run_fastlio.sh); ms/scan from its own
#    Log/fast_lio_time_log.csv, column "total time" (IMU propagation, de-skew, down-sampling,
#    iterated EKF, map update; without its PointCloud2 conversion and blind / point_filter_num
#    pass). lisfm reads the same bag with `lisfm bag_importer --preset velodyne`, then `lisfm lio`;
#    ms/scan from lio's scans.csv time_ms (the whole frame, including the scan's range filter and
#    down-sampling). Both trajectories (IMU poses) are scored with `lisfm evaluate` (SE(3)).
#    "same as folder" says whether lio on the imported folder wrote a trajectory.txt byte-identical
#    to lio on the simulated folder itself.
# LISFM_BENCH_CPU=N pins FAST-LIO2 (roscore, node, feeder) and `lisfm lio` to CPU N (taskset):
# both then run on one core (lio's TBB sees one CPU; FAST-LIO2 is single-threaded on <= 3 cores
# anyway), which keeps the comparison fair on a machine loaded by other work.
# Prints one markdown table. A benchmark, not a test: run it once; it takes ~10 min on 2 cores.
# Disk: per 120 s sequence the simulated folder (1.6 GB, kept: a re-run skips the simulation) and,
# while it runs, the bag and the imported folder (1.8 + 1.6 GB, removed after the sequence unless
# LISFM_BENCH_KEEP=1). Remove WORK_DIR when done.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_fastlio}"
DURATION="${2:-120}"
PEERS_SRC="${LISFM_PEERS_SRC:-$(cd "$LISFM_ROOT/.." && pwd)/shared/peers}"
PEERS="${PEERS:-$LISFM_BUILD_DIR/peers}"
BLIND="${FASTLIO_BLIND:-0.5}"
PIN=()
[ -n "${LISFM_BENCH_CPU:-}" ] && PIN=(taskset -c "$LISFM_BENCH_CPU")
EXP04="$LISFM_SHARED_DATA/hilti2022_groundtruth/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt"
[ -x "$LISFM" ] || { echo "bench_fastlio: build first ($LISFM missing)" >&2; exit 1; }
[ -f "$EXP04" ] || { echo "bench_fastlio: missing $EXP04 (LISFM_SHARED_DATA)" >&2; exit 1; }
[ -x "$PEERS_SRC/build_fastlio.sh" ] || { echo "bench_fastlio: no $PEERS_SRC/build_fastlio.sh" >&2; exit 3; }

echo "bench_fastlio: building FAST-LIO2 under $PEERS (log $PEERS/build_fastlio.log)"
mkdir -p "$PEERS"
if ! PEERS="$PEERS" JOBS="$LISFM_JOBS" "$PEERS_SRC/build_fastlio.sh" > "$PEERS/build_fastlio.log" 2>&1; then
  tail -n 20 "$PEERS/build_fastlio.log" >&2
  echo "bench_fastlio: error: FAST-LIO2 cannot be built on this machine (see $PEERS/build_fastlio.log)" >&2
  exit 3
fi
RUN_FASTLIO="$PEERS/fastlio/run_fastlio.sh"
mkdir -p "$WORK"

simulate() {  # name, extra args (as scripts/bench_lio.sh)
  local name=$1; shift
  if [ ! -f "$WORK/$name/groundtruth.txt" ]; then
    "$LISFM" simulate --duration "$DURATION" --camera_rate 0 --output_path "$WORK/$name" \
      --error_sources none --overwrite 1 --quiet "$@"
  fi
}

# FAST-LIO2 YAML for a sequence: upstream velodyne.yaml + the rig's LiDAR (extrinsic_T/R = rig.yaml
# T_imu_lidar, the LiDAR pose in the IMU frame: p_imu = R p_lidar + T).
fastlio_config() {  # seq_dir, out.yaml
  /usr/bin/python3 - "$1" "$2" "$BLIND" <<'PY'
import sys, yaml
seq, out, blind = sys.argv[1], sys.argv[2], float(sys.argv[3])
lid = yaml.safe_load(open(seq + "/rig.yaml"))["lidars"]
l0 = lid["lidar0"] if "lidar0" in lid else list(lid.values())[0]
T = [[float(v) for v in row] for row in l0["T_imu_lidar"]]
num = lambda x: repr(0.0 if abs(x) < 1e-15 else float(x))
R = ",\n                   ".join(", ".join(num(T[r][c]) for c in range(3)) for r in range(3))
open(out, "w").write(f"""# FAST-LIO2 config for {seq} (scripts/bench_fastlio.sh): upstream config/velodyne.yaml and
# mapping_velodyne.launch defaults; topics of `lisfm bag_exporter --preset velodyne`; the rig's LiDAR.
common:
    lid_topic:  "/velodyne_points"
    imu_topic:  "/imu/data"
    time_sync_en: false
    time_offset_lidar_to_imu: 0.0
preprocess:
    lidar_type: 2
    scan_line: {int(l0.get("rings", 32))}
    scan_rate: {int(l0.get("scan_rate", 10))}
    timestamp_unit: 0            # `time` float32 seconds since header.stamp
    blind: {blind}
mapping:
    acc_cov: 0.1
    gyr_cov: 0.1
    b_acc_cov: 0.0001
    b_gyr_cov: 0.0001
    fov_degree:    180
    det_range:     100.0
    extrinsic_est_en:  false
    extrinsic_T: [ {", ".join(num(T[r][3]) for r in range(3))} ]
    extrinsic_R: [ {R} ]
publish:
    path_en:  false
    scan_publish_en:  false
    dense_publish_en: false
    scan_bodyframe_pub_en: false
pcd_save:
    pcd_save_en: false
    interval: -1
feature_extract_enable: false
point_filter_num: 4
max_iteration: 3
filter_size_surf: 0.5
filter_size_map: 0.5
cube_side_length: 1000.0
runtime_pos_log_enable: true
""")
PY
}

evaluate() {  # groundtruth, estimate, out_dir
  "$LISFM" evaluate --reference_path "$1" --estimate_path "$2" --max_dt 0.006 \
    --output_path "$3" --overwrite 1 --quiet > /dev/null 2>> "$WORK/evaluate.log"
}

simulate office_exp04 --scene office --trajectory_path "$EXP04"
simulate staircase --scene staircase --Walk.num_stops 3

rows=()
for seq in office_exp04 staircase; do
  S="$WORK/$seq"
  bag="$WORK/$seq.bag"
  rm -f "$bag"
  "$LISFM" bag_exporter --input_path "$S" --output_path "$bag" --preset velodyne --quiet \
    2> "$WORK/${seq}_export.log"
  fastlio_config "$S" "$WORK/${seq}_fastlio.yaml"

  # FAST-LIO2 on the bag
  fl="$WORK/out_${seq}_fastlio"
  rm -rf "$fl"
  start=$(date +%s%N)
  ${PIN[@]+"${PIN[@]}"} "$RUN_FASTLIO" "$bag" "$fl" "$WORK/${seq}_fastlio.yaml" > "$WORK/${seq}_fastlio_run.log" 2>&1 \
    || { cat "$WORK/${seq}_fastlio_run.log" >&2; echo "bench_fastlio: FAST-LIO2 failed on $bag" >&2; exit 4; }
  fl_wall=$(( $(date +%s%N) - start ))
  evaluate "$S/groundtruth.txt" "$fl/fastlio_odom.tum" "$fl/eval"

  # lisfm on the same bag: bag_importer -> lio
  imp="$WORK/${seq}_from_bag"
  ours="$WORK/out_${seq}_lisfm"
  rm -rf "$imp" "$ours"
  start=$(date +%s%N)
  "$LISFM" bag_importer --input_path "$bag" --output_path "$imp" --preset velodyne \
    --rig_path "$S/rig.yaml" --quiet 2> "$WORK/${seq}_import.log"
  import_wall=$(( $(date +%s%N) - start ))
  start=$(date +%s%N)
  ${PIN[@]+"${PIN[@]}"} "$LISFM" lio --input_path "$imp" --output_path "$ours" \
    --write_keyframes 0 --quiet \
    2> "$WORK/${seq}_lio.log"
  lio_wall=$(( $(date +%s%N) - start ))
  evaluate "$S/groundtruth.txt" "$ours/trajectory.txt" "$ours/eval"
  # the same lio on the simulated folder itself: the bag round trip must not change the result
  direct="$WORK/out_${seq}_lisfm_direct"
  rm -rf "$direct"
  "$LISFM" lio --input_path "$S" --output_path "$direct" --write_keyframes 0 --quiet \
    2> "$WORK/${seq}_lio_direct.log"
  same=no
  cmp -s "$direct/trajectory.txt" "$ours/trajectory.txt" && same=yes
  # the bag and the imported folder are ~1.7 GB each per 120 s: keep only the results
  [ "${LISFM_BENCH_KEEP:-0}" = 1 ] || rm -rf "$bag" "$imp"

  rows+=("$(/usr/bin/python3 - "$seq" "$fl" "$ours" "$fl_wall" "$import_wall" "$lio_wall" "$same" <<'PY'
import csv, json, statistics, sys
seq, fl, ours = sys.argv[1:4]
fl_wall, import_wall, lio_wall = (float(v) * 1e-9 for v in sys.argv[4:7])
same = sys.argv[7]

def pct(v, q):
    v = sorted(v)
    return v[int(q * (len(v) - 1))]

def errors(d):
    m = json.load(open(d + "/eval/metrics.json"))
    ate = m["ate"]["translation_m"]
    rpe1 = [w for w in m["rpe"]["distance"] if abs(w["distance_m"] - 1.0) < 1e-9]
    rpe1 = rpe1[0]["translation_m"]["rmse"] if rpe1 else float("nan")
    return ate["rmse"] * 100, ate["max"] * 100, rpe1 * 100

# lisfm lio: scans.csv, time_ms of processed frames; span = first to last frame stamp
rows = [r for r in csv.reader(open(ours + "/scans.csv")) if not r[0].startswith("#")]
done = [r for r in rows if r[1] == "1"]
t_ours = [float(r[6]) for r in done]
span = (int(rows[-1][0]) - int(rows[0][0])) * 1e-9
# FAST-LIO2: its time log, column 2 "total time" in s (header line first)
t_fl = []
for r in csv.reader(open(fl + "/fast_lio_time_log.csv")):
    try:
        t_fl.append(float(r[1]) * 1e3)
    except (ValueError, IndexError):
        pass
n_fl = sum(1 for l in open(fl + "/fastlio_odom.tum") if l.strip() and not l.startswith("#"))
out = []
for name, t, n, wall, d in (("FAST-LIO2", t_fl, n_fl, fl_wall, fl),
                            ("lisfm lio", t_ours, len(done), lio_wall, ours)):
    a, amax, r1 = errors(d)
    out.append(f"| {seq} | {name} | {n}/{len(rows)} | {statistics.median(t):.2f} | {pct(t, 0.95):.2f} | "
               f"{span / (sum(t) / 1000):.0f}x | {wall:.1f} | {a:.2f} | {amax:.2f} | {r1:.2f} | "
               + ("-" if name == "FAST-LIO2" else f"{same} (import {import_wall:.1f} s)") + " |")
med_fl, med_ours = statistics.median(t_fl), statistics.median(t_ours)
out.append(f"| {seq} | ratio lisfm / FAST-LIO2 | | {med_ours / med_fl:.2f} | "
           f"{pct(t_ours, 0.95) / pct(t_fl, 0.95):.2f} | | | {errors(ours)[0] / errors(fl)[0]:.2f} | | | |")
print("\n".join(out))
PY
)")
done

echo
echo "FAST-LIO2 (7cc4175, $(grep -o 'CXX_FLAGS: .*' "$PEERS/fastlio/BUILD_INFO" | head -1)) vs lisfm lio on the same bag"
echo "($(nproc) cores, $(lscpu | sed -n 's/Model name: *//p' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%FT%TZ)); sequences ${DURATION} s; FAST-LIO2 blind ${BLIND} m${LISFM_BENCH_CPU:+; both pinned to CPU $LISFM_BENCH_CPU}"
echo
echo "| sequence | system | poses / scans | median ms/scan | p95 ms | RTF (per-scan time) | wall s (whole run) | ATE rmse cm | ATE max cm | RPE 1 m cm | same as folder |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
