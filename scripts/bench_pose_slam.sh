#!/usr/bin/env bash
# pose_slam benchmark: `lisfm lio` then `lisfm pose_slam` on simulated HILTI-style
# sequences with the default error sources (calibration, IMU), side by side:
# ATE (SE(3) alignment), HILTI 2022 score on the control points, ICP pairs
# (candidates / kept), per-stage times, and the honesty of the keyframe
# covariances (NEES and 95 % ellipsoid coverage, ground truth aligned at the first
# keyframe, the gauge, not by least squares). On the long scene, ablation rows
# switch the factor groups on one by one.
#   scripts/bench_pose_slam.sh [WORK_DIR] [LONG_SCENE] [SHORT_DURATION_S] [LONG_DURATION_S]
#   defaults: /tmp/lisfm_bench_pose_slam, site, 120, 300
# The long scene runs with seeds LISFM_POSE_SLAM_SEEDS (default "4 5 6"); when
# `lisfm simulate --scene LONG_SCENE` is unknown it falls back to hall.
# LISFM_POSE_SLAM_SHORT=0 skips the 120 s sequences, LISFM_POSE_SLAM_ABLATION=0
# the ablation rows (on the first seed).
# Assumes a built tree (scripts/test.sh or scripts/demo.sh builds it).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_pose_slam}"
LONG_SCENE="${2:-site}"
SHORT_DURATION="${3:-120}"
LONG_DURATION="${4:-300}"
[ -x "$LISFM" ] || { echo "bench_pose_slam: build first ($LISFM missing)" >&2; exit 1; }
mkdir -p "$WORK"

if ! "$LISFM" simulate -h | grep -q -- "--scene.*$LONG_SCENE"; then
  if [ ! -f "$LISFM_ROOT/configs/sim_$LONG_SCENE.yaml" ]; then
    echo "bench_pose_slam: scene '$LONG_SCENE' unknown to lisfm simulate: using hall" >&2
    LONG_SCENE=hall
  fi
fi

simulate() {  # name, duration, extra args
  local name=$1 duration=$2; shift 2
  if [ ! -f "$WORK/$name/groundtruth.txt" ]; then
    "$LISFM" simulate --duration "$duration" --camera_rate 0 --output_path "$WORK/$name" \
      --overwrite 1 --quiet "$@"
  fi
  if [ ! -f "$WORK/lio_$name/trajectory.txt" ]; then
    "$LISFM" lio --input_path "$WORK/$name" --output_path "$WORK/lio_$name" --overwrite 1 --quiet
  fi
}

# score NAME SEQ ESTIMATE_TRAJECTORY [POSE_SLAM_OUT] -> one table row
score() {
  local name=$1 seq=$2 trajectory=$3 out=${4:-}
  local eval="$WORK/eval_$name"
  rm -rf "$eval" "$eval.cp"
  "$LISFM" evaluate --reference_path "$WORK/$seq/groundtruth.txt" --estimate_path "$trajectory" \
    --output_path "$eval" --quiet > /dev/null
  "$LISFM" evaluate --reference_path "$WORK/$seq/controlpoints.txt" \
    --reference_type control_points --estimate_path "$trajectory" --output_path "$eval.cp" \
    --quiet > /dev/null
  /usr/bin/python3 - "$name" "$WORK/$seq" "$eval" "$out" <<'PY'
import json, math, sys
name, seq, eval_dir, out = sys.argv[1:5]
m = json.load(open(eval_dir + "/metrics.json"))
cp = json.load(open(eval_dir + ".cp/metrics.json"))
ate = m["ate"]["translation_m"]["rmse"]
def find_score(d):
    if isinstance(d, dict):
        for k, v in d.items():
            if "score" in k and isinstance(v, (int, float)):
                return v
            r = find_score(v)
            if r is not None:
                return r
    return None
score = find_score(cp)
row = [name, f"{ate * 100:.2f}", f"{score:.1f}" if score is not None else "-"]
if not out:
    print("| " + " | ".join(row + ["-"] * 6) + " |")
    sys.exit()
s = json.load(open(out + "/pose_slam_summary.json"))
p, t = s["pairs"], s["seconds"]
# NEES of the keyframe poses: ground truth aligned at the first keyframe (the
# gauge); error xi = [Log(R^T R_gt); R^T (t_gt - t)] on the manifold of the
# covariances (right perturbation), NEES = xi^T C^-1 xi, 6 dof.
def qmul(a, b):
    ax, ay, az, aw = a; bx, by, bz, bw = b
    return (aw*bx + ax*bw + ay*bz - az*by, aw*by - ax*bz + ay*bw + az*bx,
            aw*bz + ax*by - ay*bx + az*bw, aw*bw - ax*bx - ay*by - az*bz)
def qinv(q): return (-q[0], -q[1], -q[2], q[3])
def rot(q, v): return qmul(qmul(q, (v[0], v[1], v[2], 0.0)), qinv(q))[:3]
def mul(A, B):
    r = rot(A[0], B[1]); return (qmul(A[0], B[0]), tuple(a + b for a, b in zip(A[1], r)))
def inv(A):
    qi = qinv(A[0]); r = rot(qi, A[1]); return (qi, tuple(-x for x in r))
def qlog(q):
    if q[3] < 0: q = tuple(-x for x in q)
    n = math.sqrt(q[0]**2 + q[1]**2 + q[2]**2)
    if n < 1e-12: return (2*q[0], 2*q[1], 2*q[2])
    a = 2 * math.atan2(n, q[3]); return tuple(a * x / n for x in q[:3])
def tum(path):
    d = {}
    for l in open(path):
        if l.startswith("#") or not l.strip(): continue
        v = l.split()
        d[round(float(v[0]) * 1e3)] = (tuple(map(float, v[4:8])), tuple(map(float, v[1:4])))
    return d
def solve(C, x):  # C^-1 x by Gaussian elimination with partial pivoting
    n = len(x); A = [list(C[i]) + [x[i]] for i in range(n)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(A[r][c])); A[c], A[p] = A[p], A[c]
        for r in range(c + 1, n):
            f = A[r][c] / A[c][c]
            for k in range(c, n + 1): A[r][k] -= f * A[c][k]
    y = [0.0] * n
    for r in reversed(range(n)):
        y[r] = (A[r][n] - sum(A[r][k] * y[k] for k in range(r + 1, n))) / A[r][r]
    return y
gt = tum(seq + "/groundtruth.txt"); kf = tum(out + "/keyframes.txt")
keys = [k for k in sorted(kf) if k in gt]
align = mul(gt[keys[0]], inv(kf[keys[0]]))
covs = {}
for l in open(out + "/keyframe_covariances.txt"):
    if l.startswith("#") or not l.strip(): continue
    v = l.split(); u = list(map(float, v[1:])); C = [[0.0] * 6 for _ in range(6)]; i = 0
    for r in range(6):
        for c in range(r, 6): C[r][c] = C[c][r] = u[i]; i += 1
    covs[round(int(v[0]) * 1e-6)] = C
nees = []
for k in keys[1:]:
    T = mul(align, kf[k]); E = mul(inv(T), gt[k])
    xi = list(qlog(E[0])) + list(E[1])
    nees.append(sum(a * b for a, b in zip(xi, solve(covs[k], xi))))
mean_nees = sum(nees) / len(nees)
coverage = sum(1 for n in nees if n <= 12.5916) / len(nees)
stages = f"{t['icp']:.0f} / {t['solve'] + t['second_solve']:.1f} / {t['covariances']:.1f} / {t['total']:.0f}"
row += [f"{p['candidates']} / {p['kept']}",
        f"{p['rejected_lio_difference']} / {p['rejected_unconverged'] + p['rejected_degenerate'] + p['rejected_failed']} / {p['rejected_residual']}",
        str(len(s["stationary_periods"])), f"{mean_nees:.1f}", f"{coverage * 100:.0f}", stages]
print("| " + " | ".join(row) + " |")
PY
}

# pose_slam NAME SEQ [options...] -> row
pose_slam() {
  local name=$1 seq=$2; shift 2
  local out="$WORK/ps_$name"
  "$LISFM" pose_slam --input_path "$WORK/$seq" --lio_path "$WORK/lio_$seq" --output_path "$out" \
    --overwrite 1 --quiet "$@"
  score "$name" "$seq" "$out/trajectory.txt" "$out"
}

rows=()
if [ "${LISFM_POSE_SLAM_SHORT:-1}" != 0 ]; then
  for scene in office staircase hall; do
    simulate "$scene" "$SHORT_DURATION" --scene "$scene"
    rows+=("$(score "$scene lio" "$scene" "$WORK/lio_$scene/trajectory.txt")")
    rows+=("$(pose_slam "$scene" "$scene")")
  done
fi
read -r -a SEEDS <<< "${LISFM_POSE_SLAM_SEEDS:-4 5 6}"
for seed in "${SEEDS[@]}"; do
  seq="${LONG_SCENE}_long_$seed"
  simulate "$seq" "$LONG_DURATION" --scene "$LONG_SCENE" --seed "$seed"
  rows+=("$(score "$seq lio" "$seq" "$WORK/lio_$seq/trajectory.txt")")
  rows+=("$(pose_slam "$seq" "$seq")")
done
ablation=()
if [ "${LISFM_POSE_SLAM_ABLATION:-1}" != 0 ]; then
  seq="${LONG_SCENE}_long_${SEEDS[0]}"
  ablation+=("$(pose_slam "odometry only" "$seq" --PoseSlam.use_icp_pairs 0 --PoseSlam.use_imu 0 \
    --PoseSlam.use_zero_velocity 0)")
  ablation+=("$(pose_slam "+ ICP pairs" "$seq" --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0)")
  ablation+=("$(pose_slam "+ IMU (one bias)" "$seq" --PoseSlam.piecewise_bias 0 \
    --PoseSlam.use_zero_velocity 0)")
  ablation+=("$(pose_slam "+ piecewise bias" "$seq" --PoseSlam.use_zero_velocity 0)")
  ablation+=("$(pose_slam "+ zero velocity (all)" "$seq")")
fi

header="| run | ATE rmse cm | HILTI score | pairs candidates / kept | rejected off-lio / ICP failed / residual | rests | mean NEES (6) | 95 % coverage % | time s: ICP / solve / covariances / total |"
echo
echo "lisfm pose_slam benchmark ($(nproc) cores, $(lscpu | sed -n 's/Model name: *//p' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg)); default error sources; short ${SHORT_DURATION} s, long scene ${LONG_SCENE} ${LONG_DURATION} s seeds ${SEEDS[*]}"
echo
echo "$header"
echo "|---|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
if [ ${#ablation[@]} -gt 0 ]; then
  echo
  echo "Ablation on ${LONG_SCENE}_long_${SEEDS[0]}:"
  echo
  echo "$header"
  echo "|---|---|---|---|---|---|---|---|---|"
  printf '%s\n' "${ablation[@]}"
fi
