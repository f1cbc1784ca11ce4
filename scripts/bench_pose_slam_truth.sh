#!/usr/bin/env bash
# pose_slam with ground truth as its "lio" input: every factor group alone must
# leave ground-truth keyframes (nearly) where they are; one that moves them has a
# convention, time or frame error or a shared (systematic) error its covariance
# does not hold. Also reports the kept Bayesian ICP pairs against ground truth:
# NEES per pair and the mean (signed) error per index-step bin, which shows a
# bias shared by the pairs (independent errors average to 0 over hundreds of pairs).
# The last runs repeat the ICP pairs with the association options the shared pitch bias
# came from (min_planarity 0.1, the nearest-range visibility gate), and without gates, and
# on a hall scene the share of visible floor / ceiling points the visibility gate's
# range image rejects (1 deg elevation bins as in icp.cc, and 0.1 deg for contrast), and
# the normals of the far floor / ceiling that min_planarity 0.1 keeps and drops.
#   scripts/bench_pose_slam_truth.sh SEQ LIO WORK_DIR
# SEQ: a `lisfm simulate` folder (groundtruth.csv), LIO: `lisfm lio` on it (its
# keyframe clouds are reused; its stamps give the scan and keyframe times). The
# fake lio folder holds ground truth (world_from_imu, the simulator's world, linear /
# slerp interpolation of the 100 Hz ground truth) at lio's stamps.
# Assumes a built tree.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
SEQ="$1"; LIO="$2"; WORK="$3"
[ -x "$LISFM" ] || { echo "bench_pose_slam_truth: build first ($LISFM missing)" >&2; exit 1; }
mkdir -p "$WORK"

TOOLS="$WORK/truth_tools.py"
cat > "$TOOLS" <<'PY'
import bisect, math, os, sys
def qmul(a, b):
    ax, ay, az, aw = a; bx, by, bz, bw = b
    return (aw*bx + ax*bw + ay*bz - az*by, aw*by - ax*bz + ay*bw + az*bx,
            aw*bz + ax*by - ay*bx + az*bw, aw*bw - ax*bx - ay*by - az*bz)
def qconj(a): return (-a[0], -a[1], -a[2], a[3])
def qrot(q, v): return qmul(qmul(q, (v[0], v[1], v[2], 0.0)), qconj(q))[:3]
def qlog(q):
    if q[3] < 0: q = tuple(-x for x in q)
    n = math.sqrt(q[0]**2 + q[1]**2 + q[2]**2)
    if n < 1e-12: return (2*q[0], 2*q[1], 2*q[2])
    a = 2*math.atan2(n, q[3]); return tuple(a*x/n for x in q[:3])
def slerp(a, b, s):
    d = sum(x*y for x, y in zip(a, b))
    if d < 0: b = [-x for x in b]; d = -d
    if d > 0.9999995: r = [x + s*(y - x) for x, y in zip(a, b)]
    else:
        th = math.acos(d)
        r = [(math.sin((1 - s)*th)*x + math.sin(s*th)*y)/math.sin(th) for x, y in zip(a, b)]
    n = math.sqrt(sum(x*x for x in r)); return [x/n for x in r]
class Truth:
    def __init__(self, seq):
        self.t, self.p, self.q = [], [], []
        for line in open(seq + "/groundtruth.csv"):
            if line.startswith("#") or not line.strip(): continue
            v = line.split(","); w, x, y, z = (float(a) for a in v[4:8])
            self.t.append(int(v[0])); self.p.append([float(a) for a in v[1:4]]); self.q.append([x, y, z, w])
    def __call__(self, t_ns):
        k = max(0, min(bisect.bisect_right(self.t, t_ns) - 1, len(self.t) - 2))
        s = (t_ns - self.t[k]) / (self.t[k + 1] - self.t[k])
        return ([a + s*(b - a) for a, b in zip(self.p[k], self.p[k + 1])],
                slerp(self.q[k], self.q[k + 1], s))
def rel(pa, qa, pb, qb):
    return qrot(qconj(qa), [b - a for a, b in zip(pa, pb)]), qmul(qconj(qa), qb)
def tum_ns(field):
    sec, frac = field.split("."); return int(sec)*10**9 + int(frac.ljust(9, "0"))
def make_lio(seq, lio, out):
    gt = Truth(seq); os.makedirs(out + "/keyframes", exist_ok=True)
    lines = open(lio + "/trajectory.txt").read().splitlines()
    with open(out + "/trajectory.txt", "w") as f:
        f.write(lines[0] + "\n")
        for line in lines[1:]:
            if not line.strip() or line.startswith("#"): continue
            t = tum_ns(line.split()[0]); p, q = gt(t)
            f.write("%d.%09d %s\n" % (t // 10**9, t % 10**9, " ".join("%.12f" % x for x in p + q)))
    lines = open(lio + "/keyframes/keyframes.csv").read().splitlines()
    with open(out + "/keyframes/keyframes.csv", "w") as f:
        f.write(lines[0] + "\n")
        for line in lines[1:]:
            if not line.strip() or line.startswith("#"): continue
            t = int(line.split(",")[0]); p, q = gt(t)
            f.write("%d,%s\n" % (t, ",".join("%.12f" % x for x in p + q)))
            dst = out + "/keyframes/%d.pcd" % t
            if not os.path.exists(dst): os.symlink(os.path.abspath(lio + "/keyframes/%d.pcd" % t), dst)
def report(seq, out, name):
    gt = Truth(seq); kf = []
    for line in open(out + "/keyframes.txt"):
        if line.startswith("#") or not line.strip(): continue
        v = line.split(); kf.append((tum_ns(v[0]), [float(x) for x in v[1:4]], [float(x) for x in v[4:8]]))
    se = re = 0.0
    for t, p, q in kf:
        pg, qg = gt(t); se += sum((a - b)**2 for a, b in zip(p, pg))
        re += sum(x*x for x in qlog(qmul(qconj(q), qg)))
    print("| %s | %.2f | %.4f |" % (name, 1000*math.sqrt(se/len(kf)), math.degrees(math.sqrt(re/len(kf)))), end="")
    stamps = [k[0] for k in kf]; bins = {}; nees = []
    path = out + "/constraints.txt"
    for l in (open(path) if os.path.exists(path) else []):
        if not l.strip() or l.startswith("#"): continue
        v = l.split(); ti, tj = int(v[0]), int(v[1]); t = [float(x) for x in v[2:5]]
        q = [float(x) for x in v[5:9]]; c = [float(x) for x in v[9:30]]
        pa, qa = gt(ti); pb, qb = gt(tj); tg, qg = rel(pa, qa, pb, qb)
        xi = list(qlog(qmul(qconj(q), qg))) + list(qrot(qconj(q), [b - a for a, b in zip(t, tg)]))
        C = [[0.0]*6 for _ in range(6)]; k = 0
        for a in range(6):
            for b in range(a, 6): C[a][b] = C[b][a] = c[k]; k += 1
        # NEES by Gauss-Jordan (6x6)
        A = [C[r][:] + [xi[r]] for r in range(6)]
        for col in range(6):
            piv = max(range(col, 6), key=lambda r: abs(A[r][col])); A[col], A[piv] = A[piv], A[col]
            for r in range(6):
                if r != col:
                    f = A[r][col]/A[col][col]; A[r] = [x - f*y for x, y in zip(A[r], A[col])]
        nees.append(sum(xi[r]*A[r][6]/A[r][r] for r in range(6)))
        step = stamps.index(tj) - stamps.index(ti)
        bins.setdefault(step // 5 * 5, []).append((math.sqrt(sum(x*x for x in tg)), xi))
    if not nees: print(" - | - |"); return
    print(" %d | %.1f / %.0f |" % (len(nees), sum(nees)/len(nees), 100.0*sum(x < 12.59 for x in nees)/len(nees)))
    for s in sorted(bins):
        b = bins[s]; n = len(b); m = [sum(x[1][k] for x in b)/n for k in range(6)]
        print("    steps %d-%d: %d pairs, %.1f m apart; mean error (truth - pair, pair frame): "
              "rotation [%s] deg, translation [%s] mm" % (s, s + 4, n, sum(x[0] for x in b)/n,
              ", ".join("%+.4f" % math.degrees(x) for x in m[:3]),
              ", ".join("%+.2f" % (1000*x) for x in m[3:])))
def rig_imu_from_lidar(seq):  # lidar0's T_imu_lidar of the simulated rig.yaml, 3x4
    lines = open(seq + "/rig.yaml").read().splitlines()
    k = next(i for i, l in enumerate(lines) if l.strip() == "T_imu_lidar:")
    return [[float(x) for x in lines[k + 1 + r].strip(" -[]").split(",")] for r in range(3)]
def gate(seq, lio, step, elevation_bins_per_deg):
    """Share of a source keyframe's floor / ceiling points (at ground truth, hall: z 0 and
    3 m) that KdTreeTarget::Visible (icp.cc: per 0.5 x 1 deg bin the nearest target range,
    visible if r <= 1.02 nearest + 0.1 m) rejects, with the target in its LiDAR frame."""
    import struct
    gt = Truth(seq); E = rig_imu_from_lidar(seq); step = int(step); eb = float(elevation_bins_per_deg)
    kfs = [int(l.split(",")[0]) for l in open(lio + "/keyframes/keyframes.csv") if l[0].isdigit()]
    def cloud(t):
        data = open(lio + "/keyframes/%d.pcd" % t, "rb").read(); i = data.index(b"DATA binary\n") + 12
        return [struct.unpack_from("<fff", data, i + 22*k) for k in range((len(data) - i)//22)]
    def lidar(p):  # imu -> lidar
        d = [p[i] - E[i][3] for i in range(3)]; return [sum(E[r][c]*d[r] for r in range(3)) for c in range(3)]
    def bin_of(d):
        r = math.sqrt(sum(x*x for x in d)); az = math.degrees(math.atan2(d[1], d[0]))
        el = math.degrees(math.asin(max(-1.0, min(1.0, d[2]/r))))
        return (int(math.floor(el*eb)), min(max(int((az + 180)*2), 0), 719)), r
    total, rejected = {}, {}
    for a in range(0, len(kfs) - step, 8):
        ta, tb = kfs[a], kfs[a + step]; (pa, qa), (pb, qb) = gt(ta), gt(tb)
        nearest = {}
        for p in cloud(ta):
            b, r = bin_of(lidar(p))
            if r > 0 and (b not in nearest or r < nearest[b]): nearest[b] = r
        for p in cloud(tb)[::4]:
            w = [x + y for x, y in zip(qrot(qb, p), pb)]
            kind = "floor" if abs(w[2]) < 0.02 else "ceiling" if abs(w[2] - 3.0) < 0.02 else None
            if kind is None: continue
            b, r = bin_of(lidar(qrot(qconj(qa), [x - y for x, y in zip(w, pa)])))
            key = (kind, min(int(math.hypot(w[0] - pa[0], w[1] - pa[1]) // 5) * 5, 20))
            total[key] = total.get(key, 0) + 1
            if b in nearest and r > 1.02*nearest[b] + 0.1: rejected[key] = rejected.get(key, 0) + 1
    for k in sorted(total):
        print("    %d elevation bins/deg: %s %d+ m from the target: %d points, %.1f %% rejected" % (
            eb, k[0], k[1], total[k], 100.0*rejected.get(k, 0)/total[k]))
def planarity(seq, lio, index):
    """Keyframe `index` as an ICP target (0.1 m voxel centroids, PCA of <= 20 neighbours within
    1 m as in normals.cc): per distance from its sensor, the share of floor / ceiling points
    (hall: z 0 and 3 m) with planarity >= 0.1 (Bayesian min_planarity) and the mean normal tilt
    (deg, + toward the sensor) of those kept and of those dropped."""
    import struct
    gt = Truth(seq); kfs = [int(l.split(",")[0]) for l in open(lio + "/keyframes/keyframes.csv") if l[0].isdigit()]
    t = kfs[int(index)]; p0, q0 = gt(t)
    data = open(lio + "/keyframes/%d.pcd" % t, "rb").read(); i = data.index(b"DATA binary\n") + 12
    vox = {}
    for k in range((len(data) - i)//22):
        w = [x + y for x, y in zip(qrot(q0, struct.unpack_from("<fff", data, i + 22*k)), p0)]
        c = vox.setdefault(tuple(math.floor(x/0.1) for x in w), [0, 0.0, 0.0, 0.0]); c[0] += 1
        for j in range(3): c[j + 1] += w[j]
    pts = [[c[j + 1]/c[0] for j in range(3)] for c in vox.values()]
    grid = {}
    for q in pts: grid.setdefault(tuple(math.floor(x) for x in q), []).append(q)
    def smallest_eigenvector(C):  # Jacobi rotations; eigenvalues ascending
        A = [r[:] for r in C]; V = [[float(a == b) for b in range(3)] for a in range(3)]
        for _ in range(40):
            a, b = max(((0, 1), (0, 2), (1, 2)), key=lambda e: abs(A[e[0]][e[1]]))
            if abs(A[a][b]) < 1e-18: break
            th = 0.5*math.atan2(2*A[a][b], A[b][b] - A[a][a]); c, s = math.cos(th), math.sin(th)
            for k in range(3): A[k][a], A[k][b] = c*A[k][a] - s*A[k][b], s*A[k][a] + c*A[k][b]
            for k in range(3): A[a][k], A[b][k] = c*A[a][k] - s*A[b][k], s*A[a][k] + c*A[b][k]
            for k in range(3): V[k][a], V[k][b] = c*V[k][a] - s*V[k][b], s*V[k][a] + c*V[k][b]
        o = sorted(range(3), key=lambda k: A[k][k])
        return [A[k][k] for k in o], [V[0][o[0]], V[1][o[0]], V[2][o[0]]]
    bins = {}
    for q in pts[::2]:
        kind = "floor" if abs(q[2]) < 0.03 else "ceiling" if abs(q[2] - 3.0) < 0.03 else None
        d = math.hypot(q[0] - p0[0], q[1] - p0[1])
        if kind is None or d < 1: continue
        cell = tuple(math.floor(x) for x in q); near = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for o in grid.get((cell[0] + dx, cell[1] + dy, cell[2] + dz), ()):
                        e = sum((a - b)**2 for a, b in zip(o, q))
                        if e <= 1.0: near.append((e, o))
        near = [o for _, o in sorted(near)[:20]]
        if len(near) < 3: continue
        m = [sum(o[j] for o in near)/len(near) for j in range(3)]
        C = [[sum((o[a] - m[a])*(o[b] - m[b]) for o in near)/len(near) for b in range(3)] for a in range(3)]
        l, n = smallest_eigenvector(C)
        if n[2] < 0: n = [-x for x in n]
        tilt = math.degrees(math.asin(max(-1.0, min(1.0, -(n[0]*(q[0] - p0[0]) + n[1]*(q[1] - p0[1]))/d))))
        b = bins.setdefault((kind, min(int(d // 4) * 4, 20)), [[], []])
        b[0 if l[2] > 0 and (l[1] - l[0])/l[2] >= 0.1 else 1].append(tilt)
    mean = lambda v: sum(v)/len(v) if v else 0.0
    for k in sorted(bins):
        kept, dropped = bins[k]
        print("    keyframe %s: %s %d+ m: %d points, %.0f %% kept by min_planarity 0.1, normal tilt "
              "kept %+.1f (|.| %.1f), dropped %+.1f (|.| %.1f) deg" % (index, k[0], k[1],
              len(kept) + len(dropped), 100.0*len(kept)/(len(kept) + len(dropped)), mean(kept),
              mean([abs(x) for x in kept]), mean(dropped), mean([abs(x) for x in dropped])))
if __name__ == "__main__":
    {"make": make_lio, "report": report, "gate": gate, "planarity": planarity}[sys.argv[1]](*sys.argv[2:])
PY

/usr/bin/python3 "$TOOLS" make "$SEQ" "$LIO" "$WORK/truth_lio"
run() {  # name, pose_slam options...
  local name=$1; shift
  "$LISFM" pose_slam --input_path "$SEQ" --lio_path "$WORK/truth_lio" --output_path "$WORK/$name" \
    --overwrite 1 --quiet "$@" > /dev/null
  /usr/bin/python3 "$TOOLS" report "$SEQ" "$WORK/$name" "$name"
}
NO_EXTRA="--PoseSlam.imu_gyro_error 0 --PoseSlam.imu_accel_error 0
  --PoseSlam.bias_instability_gyro 0 --PoseSlam.bias_instability_accel 0"
EXACT_ODOMETRY="--PoseSlam.odometry_sigma_rotation_deg 1e-4 --PoseSlam.odometry_sigma_translation 1e-5
  --PoseSlam.odometry_sigma_rotation_deg_per_m 0 --PoseSlam.odometry_sigma_translation_per_m 0"
echo "| factors on ground truth | keyframe position RMS mm | rotation RMS deg | kept pairs | pair NEES mean / % in 95 % |"
echo "|---|---|---|---|---|"
run odometry --PoseSlam.use_icp_pairs 0 --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0
# shellcheck disable=SC2086
run imu_exact_odometry --PoseSlam.use_icp_pairs 0 --PoseSlam.use_zero_velocity 0 \
  --PoseSlam.piecewise_bias 0 $NO_EXTRA $EXACT_ODOMETRY
run imu --PoseSlam.use_icp_pairs 0 --PoseSlam.use_zero_velocity 0 --PoseSlam.piecewise_bias 0
run icp_pairs --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0
# The pair bias by association option (Bayesian defaults: min_normal_contrast 0.5, no
# min_planarity, visibility gate 0.1 m following the surface; the association before
# them: min_planarity 0.1 and the nearest-range visibility gate).
run icp_pairs_nearest_range_gate --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0 \
  --Bayesian.visibility_follows_surface 0
run icp_pairs_min_planarity_0.1 --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0 \
  --Bayesian.min_planarity 0.1 --Bayesian.min_normal_contrast 0
run icp_pairs_previous_association --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0 \
  --Bayesian.min_planarity 0.1 --Bayesian.min_normal_contrast 0 \
  --Bayesian.visibility_follows_surface 0
run icp_pairs_no_gates --PoseSlam.use_imu 0 --PoseSlam.use_zero_velocity 0 \
  --Bayesian.min_normal_contrast 0 --Bayesian.visibility_gate_m 0
if grep -q "scene: hall" "$SEQ/simulate_config.yaml" 2>/dev/null; then
  echo "nearest-range visibility gate on visible floor / ceiling (pairs 20 keyframes apart; 1 = the icp.cc range image):"
  /usr/bin/python3 "$TOOLS" gate "$SEQ" "$LIO" 20 1
  /usr/bin/python3 "$TOOLS" gate "$SEQ" "$LIO" 20 10
  echo "target normals of far floor / ceiling kept and dropped by min_planarity 0.1:"
  /usr/bin/python3 "$TOOLS" planarity "$SEQ" "$LIO" 30
  /usr/bin/python3 "$TOOLS" planarity "$SEQ" "$LIO" 60
fi
