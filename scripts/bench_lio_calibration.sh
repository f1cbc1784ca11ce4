#!/usr/bin/env bash
# Online LiDAR-IMU calibration of `lisfm lio` (--Lio.estimate_extrinsic,
# --Lio.estimate_time_offset) on simulated office sequences whose rig.yaml is wrong:
#   scripts/bench_lio_calibration.sh [WORK_DIR] [DURATION_S] [SEEDS]
#   (defaults: /tmp/lisfm_bench_lio_calibration, 60, "4 5 6"; estimator tuning used seeds 1 2 3)
# Each seed simulates the office walk; the data are made with the rig's calibration, which is
# kept as truth/rig.yaml (the layout `lisfm simulate` uses for its calibration error source),
# while rig.yaml gets lidar0's T_imu_lidar rotated by ROT_DEG about a random axis, translated by
# TRANS_MM in a random direction and its time offset moved by +-TIME_MS (drawn from the seed).
# lio then runs with the wrong calibration fixed, with each estimation on, and with the true
# calibration; the table gives ATE and the calibration error before/after against
# truth/rig.yaml, and the median ms/scan. LISFM_REPEATS=N repeats the timing-relevant runs
# N times in alternating order (median of the medians). LISFM_LIO_ARGS adds options to every
# `lisfm lio` run, LISFM_SIM_ARGS to `lisfm simulate` (e.g. "--noise_scale 0"; use a fresh WORK_DIR),
# LISFM_RUNS selects runs (default: all six of the table).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_lio_calibration}"
DURATION="${2:-60}"
SEEDS="${3:-4 5 6}"
ROT_DEG="${ROT_DEG:-0.2}"
TRANS_MM="${TRANS_MM:-5}"
TIME_MS="${TIME_MS:-3}"
REPEATS="${LISFM_REPEATS:-1}"
read -r -a LIO_ARGS <<< "${LISFM_LIO_ARGS:-}"
read -r -a SIM_ARGS <<< "${LISFM_SIM_ARGS:-}"
[ -x "$LISFM" ] || { echo "bench_lio_calibration: build first ($LISFM missing)" >&2; exit 1; }
mkdir -p "$WORK"

# Sequence folder with the wrong rig.yaml: the recorded files are linked, truth/rig.yaml is the
# rig the data were simulated with.
perturb() {  # clean_dir perturbed_dir seed
  local clean=$1 out=$2 seed=$3
  rm -rf "$out"
  mkdir -p "$out/truth"
  for f in "$clean"/*; do
    [ "$(basename "$f")" = rig.yaml ] || ln -s "$f" "$out/$(basename "$f")"
  done
  cp "$clean/rig.yaml" "$out/truth/rig.yaml"
  /usr/bin/python3 - "$clean/rig.yaml" "$out/rig.yaml" "$seed" "$ROT_DEG" "$TRANS_MM" "$TIME_MS" <<'PY'
import math, random, sys, yaml
src, dst, seed, rot_deg, trans_mm, time_ms = sys.argv[1], sys.argv[2], int(sys.argv[3]), *map(float, sys.argv[4:])
rig = yaml.safe_load(open(src))
rng = random.Random(1000 + seed)
def unit():
    v = [rng.gauss(0, 1) for _ in range(3)]
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]
def rotation(axis, angle):  # Rodrigues
    x, y, z = axis
    c, s, C = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]
lidar = rig["lidars"]["lidar0"]
T = lidar["T_imu_lidar"]
dR = rotation(unit(), math.radians(rot_deg))
R = [[sum(T[i][k] * dR[k][j] for k in range(3)) for j in range(3)] for i in range(3)]  # R * dR
dt = [x * trans_mm * 1e-3 for x in unit()]
lidar["T_imu_lidar"] = [R[i] + [T[i][3] + dt[i]] for i in range(3)] + [[0, 0, 0, 1]]
lidar["time_offset"] = lidar.get("time_offset", 0.0) + rng.choice([-1, 1]) * time_ms * 1e-3
yaml.safe_dump(rig, open(dst, "w"), default_flow_style=None, sort_keys=False)
PY
}

run_lio() {  # input output extra-args...
  local in=$1 out=$2; shift 2
  rm -rf "$out"
  "$LISFM" lio --input_path "$in" --output_path "$out" --write_keyframes 0 --quiet \
    ${LIO_ARGS[@]+"${LIO_ARGS[@]}"} "$@"
  "$LISFM" evaluate --reference_path "$in/groundtruth.txt" --estimate_path "$out/trajectory.txt" \
    --max_dt 0.006 --output_path "$out/eval" --quiet > /dev/null
}

EST_BOTH=(--Lio.estimate_extrinsic 1 --Lio.estimate_time_offset 1)
read -r -a configs <<< "${LISFM_RUNS:-wrong_fixed wrong_extrinsic wrong_time wrong_both true_fixed true_both}"
rows=()
for seed in $SEEDS; do
  clean="$WORK/office_s$seed"
  if [ ! -f "$clean/groundtruth.txt" ]; then
    "$LISFM" simulate --scene office --duration "$DURATION" --camera_rate 0 --seed "$seed" \
      --error_sources none --Walk.num_stops 3 --output_path "$clean" --overwrite 1 --quiet ${SIM_ARGS[@]+"${SIM_ARGS[@]}"}
  fi
  perturb "$clean" "$WORK/office_s${seed}_wrong" "$seed"
  for rep in $(seq 1 "$REPEATS"); do
    # Alternate the order so that load on the machine does not favour one setting.
    order=("${configs[@]}")
    if [ $((rep % 2)) -eq 0 ]; then order=($(printf '%s\n' "${configs[@]}" | tac)); fi
    for c in "${order[@]}"; do
      case $c in
        wrong_fixed) run_lio "$WORK/office_s${seed}_wrong" "$WORK/out_s${seed}_${c}_$rep" ;;
        wrong_extrinsic) run_lio "$WORK/office_s${seed}_wrong" "$WORK/out_s${seed}_${c}_$rep" \
            --Lio.estimate_extrinsic 1 ;;
        wrong_time) run_lio "$WORK/office_s${seed}_wrong" "$WORK/out_s${seed}_${c}_$rep" \
            --Lio.estimate_time_offset 1 ;;
        wrong_both) run_lio "$WORK/office_s${seed}_wrong" "$WORK/out_s${seed}_${c}_$rep" "${EST_BOTH[@]}" ;;
        true_fixed) run_lio "$clean" "$WORK/out_s${seed}_${c}_$rep" ;;
        true_both) run_lio "$clean" "$WORK/out_s${seed}_${c}_$rep" "${EST_BOTH[@]}" ;;
      esac
    done
  done
  for c in "${configs[@]}"; do
    rows+=("$(/usr/bin/python3 - "$WORK" "$seed" "$c" "$REPEATS" <<'PY'
import csv, json, math, statistics, sys, yaml
work, seed, config, repeats = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
seq = f"{work}/office_s{seed}" + ("_wrong" if config.startswith("wrong") else "")
truth = yaml.safe_load(open(f"{work}/office_s{seed}_wrong/truth/rig.yaml"))["lidars"]["lidar0"]
def errors(T, offset):
    Tt = truth["T_imu_lidar"]
    dt = math.sqrt(sum((T[i][3] - Tt[i][3]) ** 2 for i in range(3)))
    tr = sum(T[k][i] * Tt[k][i] for i in range(3) for k in range(3))  # trace(R^T R_true)
    ang = math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1) / 2))))
    return dt * 1e3, ang, abs(offset - truth.get("time_offset", 0.0)) * 1e3
rig = yaml.safe_load(open(seq + "/rig.yaml"))["lidars"]["lidar0"]
before = errors(rig["T_imu_lidar"], rig.get("time_offset", 0.0))
medians = []
for rep in range(1, repeats + 1):
    out = f"{work}/out_s{seed}_{config}_{rep}"
    t = sorted(float(r[6]) for r in csv.reader(open(out + "/scans.csv"))
               if not r[0].startswith("#") and r[1] == "1")
    medians.append(statistics.median(t))
out = f"{work}/out_s{seed}_{config}_1"
ate = json.load(open(out + "/eval/metrics.json"))["ate"]["translation_m"]
after, sig = before, ""
try:
    cal = yaml.safe_load(open(out + "/calibration.yaml"))["lidars"]["lidar0"]
    after = errors(cal["T_imu_lidar"], cal["time_offset"])
    sig = (f"{1e3 * math.sqrt(sum(x * x for x in cal['translation_std'])):.2f} / "
           f"{math.degrees(math.sqrt(sum(x * x for x in cal['rotation_std']))):.3f} / "
           f"{1e3 * cal['time_offset_std']:.3f}")
except FileNotFoundError:
    pass
print(f"| {seed} | {config} | {ate['rmse'] * 1e3:.2f} | {ate['max'] * 1e3:.2f} | "
      f"{before[0]:.2f} / {before[1]:.3f} / {before[2]:.2f} | "
      f"{after[0]:.2f} / {after[1]:.3f} / {after[2]:.2f} | {sig} | "
      f"{statistics.median(medians):.2f} |")
PY
)")
  done
done

echo
echo "lisfm lio online calibration ${LISFM_LIO_ARGS:+(${LISFM_LIO_ARGS}) }($(nproc) cores, $(lscpu | sed -n 's/Model name: *//p' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg)); office ${DURATION} s, seeds ${SEEDS}; rig.yaml off by ${ROT_DEG} deg / ${TRANS_MM} mm / ${TIME_MS} ms; ${REPEATS} timing run(s)"
echo
echo "| seed | run | ATE rmse mm | ATE max mm | calib. error before: mm / deg / ms | after | 1-sigma: mm / deg / ms | median ms/scan |"
echo "|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
