#!/usr/bin/env bash
# `lisfm pipeline` on simulated office recordings (5 cameras, default realistic error
# sources, configs/pipeline_sim.yaml): per-stage times for each duration, and on the
# stock durations (default: the first duration) the models side by side with stock
# COLMAP (colmap mapper on our pair list's matches; with --exhaustive also stock
# exhaustive matching + colmap mapper): time, registered images, camera errors against
# the simulator's ground truth.
# Prints markdown tables for docs/BENCHMARKS.md (also WORK_DIR/bench_pipeline.md) and,
# with matplotlib, WORK_DIR/growth.png (seconds per stage against duration, log-log).
#
#   scripts/bench_pipeline.sh [--durations "120 30 60 240"] [--camera_rate HZ]
#                             [--stock_durations "120" | --no_stock] [--exhaustive]
#                             [--work_dir DIR] [--config FILE]
#
# --stock_durations: the durations (among --durations) that also run stock COLMAP
# (hours-long colmap mapper on 240 s); --no_stock: none, per-stage times only.
# Defaults: --durations 120, the first duration compared with stock COLMAP,
# --camera_rate 1, no exhaustive run, WORK_DIR
# /tmp/lisfm_bench_pipeline. Each duration's recording and pipeline output are kept in
# WORK_DIR/office_<D>s/ (a rerun reuses finished stages; delete WORK_DIR for fresh times).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

DURATIONS=120
RATE=1
STOCK_DURATIONS=first
EXHAUSTIVE=0
WORK_DIR=/tmp/lisfm_bench_pipeline
CONFIG="$LISFM_ROOT/configs/pipeline_sim.yaml"
usage() { sed -n '2,20p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --durations) DURATIONS="$2"; shift 2 ;;
    --camera_rate) RATE="$2"; shift 2 ;;
    --stock_durations) STOCK_DURATIONS="$2"; shift 2 ;;
    --no_stock) STOCK_DURATIONS=""; shift ;;
    --exhaustive) EXHAUSTIVE=1; shift ;;
    --work_dir) WORK_DIR="$2"; shift 2 ;;
    --config) CONFIG="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "unknown argument: $1" >&2; usage >&2; exit 2 ;;
  esac
done
[ -x "$LISFM" ] || { echo "build lisfm first ($LISFM missing)" >&2; exit 1; }
[ "$STOCK_DURATIONS" = first ] && STOCK_DURATIONS="${DURATIONS%% *}"
for S in $STOCK_DURATIONS; do
  case " $DURATIONS " in
    *" $S "*) ;;
    *) echo "--stock_durations: $S is not one of --durations ($DURATIONS)" >&2; exit 2 ;;
  esac
done
mkdir -p "$WORK_DIR"

runs=()
for D in $DURATIONS; do
  dir="$WORK_DIR/office_${D}s"
  mkdir -p "$dir"
  if [ ! -f "$dir/sequence/rig.yaml" ]; then
    echo "== simulate ${D} s office, cameras at ${RATE} Hz ==" >&2
    /usr/bin/time -f "%e" -o "$dir/simulate_seconds.txt" \
      "$LISFM" simulate --scene office --duration "$D" --camera_rate "$RATE" --seed 1 --quiet 1 \
      --output_path "$dir/sequence" >&2
  fi
  compare=(--compare_stock 0)
  stock=0
  case " $STOCK_DURATIONS " in
    *" $D "*) stock=1; compare=(--compare_stock 1 --compare_exhaustive "$EXHAUSTIVE") ;;
  esac
  echo "== lisfm pipeline ${D} s ==" >&2
  "$LISFM" pipeline --input_path "$dir/sequence" --output_path "$dir/pipeline" \
    --config_path "$CONFIG" "${compare[@]}" >&2
  runs+=("$D:$stock:$dir")
done

/usr/bin/python3 - "$WORK_DIR" "$RATE" "${runs[@]}" <<'EOF' | tee "$WORK_DIR/bench_pipeline.md"
import json, sys
work, rate, runs = sys.argv[1], sys.argv[2], sys.argv[3:]
stages = ["lio", "pose_slam", "database_importer", "feature_extractor", "matches_importer",
          "global_mapper"]
rows = []
stock_durations = set()
for run in runs:
    d, stock, path = run.split(":", 2)
    report = json.load(open(path + "/pipeline/report.json"))
    by = {s["name"]: s for s in report["stages"]}
    rows.append((int(d), report, by))
    if stock == "1":
        stock_durations.add(int(d))

print(f"Per-stage seconds, office, 5 cameras at {rate} Hz (wall time; `pipeline` = the stages "
      "listed, without the stock comparison and the evaluation)\n")
print("| duration | images | pairs | " + " | ".join(stages) + " | pipeline |")
print("|---:|---:|---:|" + "---:|" * (len(stages) + 1))
for d, report, by in rows:
    total = sum(by[s]["seconds"] for s in stages)
    images = by["database_importer"].get("counts", {}).get("images", "-")
    pairs = by["database_importer"].get("counts", {}).get("pairs", "-")
    cells = " | ".join(f"{by[s]['seconds']:.1f}" for s in stages)
    print(f"| {d} s | {images} | {pairs} | {cells} | {total:.1f} |")

for d, report, by in rows:
    title = "Models side by side" if d in stock_durations else "lisfm's model (no stock run)"
    print(f"\n{title} ({d} s; camera errors against ground truth: lisfm's model by SE(3), "
          "stock COLMAP's by Sim(3))\n")
    print("| method | seconds | registered / images | points | reproj. [px] | alignment | "
          "position error mean / max [mm] | rotation error mean / max [deg] |")
    print("|---|---:|---:|---:|---:|---|---:|---:|")
    front = sum(by[s]["seconds"] for s in ["feature_extractor", "matches_importer"])
    for row in report["comparison"]:
        seconds = row["seconds"]
        note = ""
        if row["stage"] == "global_mapper":
            note = " (+ lio, pose_slam, importer, features, pair matching: see above)"
        if row["stage"] == "stock_mapper":
            note = " (mapper only; same features and matches)"
        if row["stage"] == "exhaustive_mapper":
            seconds += by["feature_extractor"]["seconds"]
            note = " (features + exhaustive matching + mapper)"
        cams = row.get("cameras")
        align = "-"
        if isinstance(cams, dict):
            align = ("Sim(3), scale %.3f" % cams["scale"]) if cams.get("alignment") == "sim3" else "SE(3)"
            p = cams["position_error_m"]; r = cams["rotation_error_deg"]
            pos = f"{p['mean']*1000:.2f} / {p['max']*1000:.2f}"
            rot = f"{r['mean']:.4f} / {r['max']:.4f}"
        else:
            pos, rot = (cams or "-"), "-"
        print(f"| {row['method']}{note} | {seconds:.1f} | {row.get('registered_images', '-')} / "
              f"{row.get('images', '-')} | {row.get('points', '-')} | "
              f"{row.get('mean_reprojection_error_px', float('nan')):.3f} | {align} | {pos} | {rot} |")
    if "covisibility_recall" in report:
        r = report["covisibility_recall"]
        print(f"\nCo-visibility recall: {r['listed']} of {r['exhaustive_verified_pairs']} pairs "
              f"verified by exhaustive matching are on the pair list ({100*r['recall']:.1f} %).")
    if report.get("rig"):
        print("\nRefined camera extrinsics (cam_k_from_cam0) vs truth/rig.yaml: " + "; ".join(
            f"cam{c['camera']} {c['calibration_rotation_error_deg']:.3f}° / "
            f"{c['calibration_translation_error_mm']:.1f} mm -> {c['refined_rotation_error_deg']:.3f}° / "
            f"{c['refined_translation_error_mm']:.1f} mm" for c in report["rig"]))

if len(rows) > 1:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        rows.sort(key=lambda r: r[0])
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for s in stages:
            ax.loglog([r[0] for r in rows], [max(r[2][s]["seconds"], 1e-2) for r in rows], "o-",
                      label=s)
        ax.set_xlabel("recording [s]"); ax.set_ylabel("stage wall time [s]")
        ax.grid(True, which="both", alpha=0.3); ax.legend(fontsize=8)
        fig.tight_layout(); fig.savefig(work + "/growth.png", dpi=120)
        print(f"\n(log-log plot: {work}/growth.png)")
    except ImportError:
        print("\n(no matplotlib: growth plot skipped)")
EOF
