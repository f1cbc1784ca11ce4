#!/usr/bin/env bash
# MPI scale-out of `lisfm pose_slam` (Bayesian ICP pairs), `lisfm
# database_importer` (co-visibility) and `lisfm global_mapper` (the view graph's
# two-view estimation) on one long simulated recording: one process with 2 threads
# (the normal run), one process with 1 thread, and mpirun with 1, 2 and 4 ranks (4
# oversubscribed on this 2-core machine) of 1 thread each. Prints markdown tables for
# docs/BENCHMARKS.md (also WORK_DIR/bench_mpi.md): wall time of the distributed stage
# (constraints: cloud loading + ICP pairs incl. waiting for the other ranks;
# co-visibility, and its steps on rank 0; two-view step incl. the gather), rank 0's
# serial part (pose graph build, solves, covariances, map; global_mapper: everything
# after the view graph),
# parallel efficiency against 1 rank x 1 thread, and whether every output is
# byte-identical to the normal run.
#
#   scripts/bench_mpi.sh [--scene NAME] [--duration S] [--camera_rate HZ] [--work_dir DIR]
#                        [--pipeline_path DIR] [--keep]
#
# global_mapper runs on the matched database of a `lisfm pipeline` output folder
# (matches_importer/database.db, database_importer/rig.yaml and constraints.txt, the
# pipeline's global_mapper options): --pipeline_path DIR, else the script runs `lisfm
# pipeline --end_stage matches_importer` (configs/pipeline_sim.yaml) on its recording
# (stock SIFT + matching: ~2 min per 10 s of office at 0.5 Hz under load).
# Threads: pose_slam --num_threads 1 --Solver.num_threads 1 (TBB arena of the ICP
# pairs and preintegration; Ceres), database_importer --DatabaseImporter.num_threads 1
# (TBB global_control), global_mapper --num_threads 1. The work folder is removed at
# the end unless --keep.
# Runs as root only with OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# (set here when the user is root).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

SCENE=office
DURATION=300
RATE=0.5
WORK_DIR=/tmp/lisfm_bench_mpi
KEEP=0
PIPELINE=
usage() { sed -n '2,28p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --scene) SCENE=$2; shift 2 ;;
    --duration) DURATION=$2; shift 2 ;;
    --camera_rate) RATE=$2; shift 2 ;;
    --work_dir) WORK_DIR=$2; shift 2 ;;
    --pipeline_path) PIPELINE=$2; shift 2 ;;
    --keep) KEEP=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "error: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
command -v mpirun >/dev/null || { echo "error: mpirun not found (apt-get install openmpi-bin)" >&2; exit 1; }
[ -x "$LISFM" ] || { echo "error: $LISFM not built (cmake --build build --target lisfm)" >&2; exit 1; }
if [ "$(id -u)" = 0 ]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi

mkdir -p "$WORK_DIR"
SEQ="$WORK_DIR/seq"
LIO="$WORK_DIR/lio"
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
if [ ! -f "$SEQ/rig.yaml" ]; then
  "$LISFM" simulate --scene "$SCENE" --duration "$DURATION" --camera_rate "$RATE" --quiet 1 \
    --output_path "$SEQ"
fi
[ -f "$LIO/trajectory.txt" ] || "$LISFM" lio --quiet 1 --input_path "$SEQ" --output_path "$LIO"
if [ -z "$PIPELINE" ]; then
  PIPELINE="$WORK_DIR/pipeline"
  [ -f "$PIPELINE/matches_importer/DONE" ] || "$LISFM" pipeline --input_path "$SEQ" \
    --output_path "$PIPELINE" --config_path "$LISFM_ROOT/configs/pipeline_sim.yaml" \
    --end_stage matches_importer >"$WORK_DIR/pipeline.log"
fi
[ -f "$PIPELINE/matches_importer/database.db" ] ||
  { echo "error: $PIPELINE/matches_importer/database.db not found (--pipeline_path)" >&2; exit 1; }

now() { date +%s.%N; }
# run NAME RANKS THREADS: pose_slam then database_importer; RANKS 0 = no mpirun.
run() {
  local name=$1 ranks=$2 threads=$3 launcher=() ps_threads=() db_threads=()
  # Unbound ranks: each may use both cores, as the single process does.
  [ "$ranks" -gt 0 ] && launcher=(mpirun --oversubscribe --bind-to none -np "$ranks")
  if [ "$threads" -gt 0 ]; then
    ps_threads=(--num_threads "$threads" --Solver.num_threads "$threads")
    db_threads=(--DatabaseImporter.num_threads "$threads")
  fi
  local t0 t1 t2 t3
  t0=$(now)
  "${launcher[@]}" "$LISFM" pose_slam --quiet 1 --input_path "$SEQ" --lio_path "$LIO" \
    --output_path "$WORK_DIR/ps_$name" "${ps_threads[@]}"
  t1=$(now)
  "${launcher[@]}" "$LISFM" database_importer --quiet 1 --input_path "$SEQ" \
    --pose_slam_path "$WORK_DIR/ps_1x2" --lio_path "$LIO" --output_path "$WORK_DIR/db_$name" \
    "${db_threads[@]}"
  t2=$(now)
  local gm_threads=()
  [ "$threads" -gt 0 ] && gm_threads=(--num_threads "$threads")
  "${launcher[@]}" "$LISFM" global_mapper --quiet 1 \
    --database_path "$PIPELINE/matches_importer/database.db" \
    --rig_path "$PIPELINE/database_importer/rig.yaml" \
    --lidar_constraints_path "$PIPELINE/database_importer/constraints.txt" \
    --BundleAdjustment.refine_cam_from_rig 1 --BundleAdjustment.refine_prior_frame 1 \
    --output_path "$WORK_DIR/gm_$name" "${gm_threads[@]}"
  t3=$(now)
  echo "$name $ranks $threads $t0 $t1 $t2 $t3" >>"$WORK_DIR/times.txt"
}
rm -rf "$WORK_DIR"/ps_* "$WORK_DIR"/db_* "$WORK_DIR"/gm_* "$WORK_DIR/times.txt"
run 1x2 0 0   # the normal run: one process, TBB on both cores
run 1x1 0 1
run mpi1x1 1 1
run mpi2x1 2 1
run mpi4x1 4 1
load_after=$(cut -d' ' -f1-3 /proc/loadavg)

python3 - "$WORK_DIR" "$load_before" "$load_after" "$SCENE" "$DURATION" "$RATE" "$PIPELINE" <<'PY' | tee "$WORK_DIR/bench_mpi.md"
import json, sys, filecmp, os
work, load_before, load_after, scene, duration, rate, pipeline = sys.argv[1:]
runs = []
for line in open(os.path.join(work, "times.txt")):
    name, ranks, threads, t0, t1, t2, t3 = line.split()
    ps = json.load(open(os.path.join(work, f"ps_{name}", "pose_slam_summary.json")))
    db = json.load(open(os.path.join(work, f"db_{name}", "importer_summary.json")))
    s = ps["seconds"]
    runs.append(dict(name=name, ranks=int(ranks), threads=int(threads),
                     ps_wall=float(t1) - float(t0), db_wall=float(t2) - float(t1),
                     constraints=s["load_clouds"] + s["icp"],
                     serial=s["build"] + s["solve"] + s["second_solve"] + s["covariances"] + s["map"],
                     covis=db["seconds"]["covisibility"], pairs=ps["pairs"]["registered"],
                     covis_steps=db["covisibility_seconds"]))
    gm = json.load(open(os.path.join(work, f"gm_{name}", "global_mapper_summary.json")))
    runs[-1].update(gm_wall=float(t3) - float(t2), two_view=gm["view_graph"]["seconds"],
                    gm_serial=gm["total_seconds"] - gm["view_graph"]["seconds"],
                    gm_pairs=gm["view_graph"]["pairs_in_database"])
ref = "ps_1x2", "db_1x2"
ps_files = ["trajectory.txt", "keyframes.txt", "constraints.txt", "keyframe_covariances.txt", "map.pcd"]
db_files = ["database.db", "image_list.txt", "pairs.txt", "rig.yaml", "constraints.txt", "covisibility.csv"]
gm_files = ["cameras.bin", "images.bin", "points3D.bin", "frames.bin", "rigs.bin"]
def same_gm(name):
    return all(filecmp.cmp(os.path.join(work, "gm_1x2", "0", f), os.path.join(work, f"gm_{name}", "0", f),
                           shallow=False) for f in gm_files)
def same(name):
    ok = all(filecmp.cmp(os.path.join(work, ref[0], f), os.path.join(work, f"ps_{name}", f), shallow=False) for f in ps_files)
    return ok and all(filecmp.cmp(os.path.join(work, ref[1], f), os.path.join(work, f"db_{name}", f), shallow=False) for f in db_files)
base = next(r for r in runs if r["name"] == "1x1")
print(f"{scene}, {duration} s, {rate} Hz rig frames; {runs[0]['pairs']} ICP pairs; "
      f"load average before {load_before}, after {load_after}\n")
print("| run | ranks x threads | pose_slam wall s | constraints s | rank 0 serial s | "
      "importer wall s | co-visibility s | efficiency constraints | efficiency co-visibility | "
      "identical |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in runs:
    # Efficiency over processes x threads (4 x 1 oversubscribes the 2 cores: at most 50 %).
    cores = max(1, r["ranks"]) * (r["threads"] if r["threads"] > 0 else 2)
    eff_c = base["constraints"] / (cores * r["constraints"])
    eff_v = base["covis"] / (cores * r["covis"])
    label = "1 x 2 (TBB)" if r["name"] == "1x2" else f"{max(1, r['ranks'])} x 1" + \
        (" (no mpirun)" if r["ranks"] == 0 else "")
    print(f"| {r['name']} | {label} | {r['ps_wall']:.1f} | {r['constraints']:.1f} | "
          f"{r['serial']:.1f} | {r['db_wall']:.1f} | {r['covis']:.1f} | {100 * eff_c:.0f} % | "
          f"{100 * eff_v:.0f} % | {'yes' if same(r['name']) else 'NO'} |")
print("\nco-visibility steps on rank 0, s (scans: reading the keyframe scans; map: the voxel map, "
      "on every rank; project: its share of the images; exchange: the transfers incl. waiting; "
      "tally: its share of the votes; select: pair selection, rank 0 alone):\n")
steps = ["scans", "map", "project", "exchange", "tally", "select"]
print("| run | " + " | ".join(steps) + " |")
print("|---|" + "---|" * len(steps))
for r in runs:
    print(f"| {r['name']} | " + " | ".join(f"{r['covis_steps'][k]:.2f}" for k in steps) + " |")
serial_share = base["serial"] / (base["constraints"] + base["serial"])
print(f"\nrank 0's serial part of pose_slam (1 x 1): {base['serial']:.1f} s = "
      f"{100 * serial_share:.1f} % of constraints + serial.")
print(f"\nglobal_mapper on {pipeline}/matches_importer/database.db "
      f"({runs[0]['gm_pairs']} pairs in the database):\n")
print("| run | ranks x threads | global_mapper wall s | two-view step s | rank 0 serial rest s | "
      "efficiency two-view | identical |")
print("|---|---|---|---|---|---|---|")
for r in runs:
    cores = max(1, r["ranks"]) * (r["threads"] if r["threads"] > 0 else 2)
    eff = base["two_view"] / (cores * r["two_view"])
    label = "1 x 2 (TBB)" if r["name"] == "1x2" else f"{max(1, r['ranks'])} x 1" + \
        (" (no mpirun)" if r["ranks"] == 0 else "")
    print(f"| {r['name']} | {label} | {r['gm_wall']:.1f} | {r['two_view']:.2f} | "
          f"{r['gm_serial']:.2f} | {100 * eff:.0f} % | {'yes' if same_gm(r['name']) else 'NO'} |")
gm_share = base["two_view"] / (base["two_view"] + base["gm_serial"])
print(f"\nglobal_mapper (1 x 1): the two-view step is {100 * gm_share:.1f} % of the mapping time; "
      f"the rest (averaging, tracks, bundle adjustment) runs on rank 0 alone.")
PY
[ "$KEEP" = 1 ] || rm -rf "$WORK_DIR"
