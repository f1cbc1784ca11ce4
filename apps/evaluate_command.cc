// `lisfm evaluate`: scores an estimated trajectory against ground truth.
//
//   lisfm evaluate --reference_path REF --estimate_path EST
//                  [--alignment se3|sim3|none] [--max_dt s]
//                  [--reference_type trajectory|control_points]
//                  [--output_path DIR]
//
// (--reference, --estimate and --align are accepted as aliases.)
//
// Reference type `trajectory`: nearest-time association within max_dt (default
// 0.01 s), alignment (default se3), ATE, RPE per frame and over 1/5/10 m; with
// sim3 the scale is reported. Reference type `control_points`: the HILTI 2022
// score (lever arm to the pole tip, association within max_dt, default 2 s,
// SE(3) alignment without scale). Prints a table on stdout; with --output_path
// writes metrics.json, evaluation.png and evaluate_config.yaml there.
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/evaluation.h"
#include "core/file_utils.h"
#include "core/io/plot.h"
#include "core/io/trajectory_io.h"
#include "core/logging.h"
#include "core/options.h"

namespace lisfm {

namespace {

using json = nlohmann::ordered_json;

constexpr double kDefaultTrajectoryMaxDtS = 0.01;
constexpr double kDefaultControlPointMaxDtS = 2.0;

// NaN (undefined statistic) becomes JSON null.
json Number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json StatsToJson(const ErrorStats& s) {
  return json{{"rmse", Number(s.rmse)},
              {"mean", Number(s.mean)},
              {"median", Number(s.median)},
              {"std", Number(s.std)},
              {"min", Number(s.min)},
              {"max", Number(s.max)},
              {"count", s.count}};
}

json Sim3ToJson(const Sim3& s) {
  const Quat& q = s.pose.rotation();
  const Vec3& t = s.pose.translation();
  return json{{"scale", s.scale},
              {"rotation_xyzw", {q.x(), q.y(), q.z(), q.w()}},
              {"translation_m", {t.x(), t.y(), t.z()}}};
}

std::string Cell(double v, int decimals = 4) {
  return std::isfinite(v) ? fmt::format("{:>10.{}f}", v, decimals)
                          : fmt::format("{:>10}", "-");
}

std::string StatsRow(const std::string& name,
                     const ErrorStats& s,
                     const std::string& extra = "") {
  return fmt::format("{:<24}{}{}{}{}{}{}{:>8}{}\n",
                     name,
                     Cell(s.rmse),
                     Cell(s.mean),
                     Cell(s.median),
                     Cell(s.std),
                     Cell(s.min),
                     Cell(s.max),
                     s.count,
                     extra);
}

std::string StatsHeader() {
  return fmt::format("{:<24}{:>10}{:>10}{:>10}{:>10}{:>10}{:>10}{:>8}",
                     "",
                     "rmse",
                     "mean",
                     "median",
                     "std",
                     "min",
                     "max",
                     "count");
}

// Re-throws an evaluation error with the file names it is about.
[[noreturn]] void RethrowWithFiles(const InputError& e,
                                   const std::string& reference_path,
                                   const std::string& estimate_path) {
  throw InputError(
      estimate_path,
      "",
      std::string(e.what()) + " (reference " + reference_path + ")");
}

// The alignment's rotation conditioning (core/evaluation.h AlignmentConditioning).
json ConditioningToJson(const TrajectoryEvaluation& ev) {
  const AlignmentConditioning& c = ev.alignment_conditioning;
  return json{{"rotation_sigma_deg", Number(c.rotation_sigma_rad * 180.0 / M_PI)},
              {"weak_axis", {c.weak_axis.x(), c.weak_axis.y(), c.weak_axis.z()}},
              {"position_sigma_m", c.position_sigma_m},
              {"rotation_ate_dominated_by_alignment", c.rotation_dominated}};
}

struct Outputs {
  json metrics;
  TrajectoryPlotData plot;
  std::string summary;
};

Outputs EvaluateAgainstTrajectory(const std::string& reference_path,
                                  const std::string& estimate_path,
                                  const Trajectory& estimate,
                                  const TrajectoryEvaluationOptions& options) {
  const Trajectory reference = ReadTrajectory(reference_path);
  TrajectoryEvaluation ev;
  try {
    ev = EvaluateTrajectory(reference, estimate, options);
  } catch (const InputError& e) {
    RethrowWithFiles(e, reference_path, estimate_path);
  }

  std::string table = fmt::format(
      "reference {} ({} poses)\nestimate  {} ({} poses)\nassociated {} pairs "
      "within {} s, "
      "alignment {}",
      reference_path,
      ev.num_reference,
      estimate_path,
      ev.num_estimate,
      ev.pairs.size(),
      NsToSeconds(options.max_dt_ns),
      AlignmentTypeName(ev.alignment));
  if (ev.alignment == AlignmentType::kSim3) {
    table += fmt::format(", scale {:.6f}", ev.reference_from_estimate.scale);
  }
  table += "\n\n" + StatsHeader() + "\n";
  table += StatsRow("ATE translation [m]", ev.ate_translation_m);
  table += StatsRow("ATE rotation [deg]", ev.ate_rotation_deg);
  table += StatsRow("RPE/frame trans. [m]", ev.rpe_translation_m);
  table += StatsRow("RPE/frame rot. [deg]", ev.rpe_rotation_deg);
  json windows = json::array();
  for (const DistanceRpe& w : ev.rpe_distance) {
    table +=
        StatsRow(fmt::format("RPE {:g} m trans. [m]", w.distance_m),
                 w.translation_m,
                 "  drift " + (std::isfinite(w.drift_percent)
                                   ? fmt::format("{:.3f} %", w.drift_percent)
                                   : std::string("-")));
    table += StatsRow(fmt::format("RPE {:g} m rot. [deg]", w.distance_m),
                      w.rotation_deg);
    windows.push_back({{"distance_m", w.distance_m},
                       {"translation_m", StatsToJson(w.translation_m)},
                       {"rotation_deg", StatsToJson(w.rotation_deg)},
                       {"drift_percent", Number(w.drift_percent)}});
  }
  std::cout << table;

  Outputs out;
  out.metrics = {
      {"reference_type", "trajectory"},
      {"num_reference_poses", ev.num_reference},
      {"num_estimate_poses", ev.num_estimate},
      {"num_associated", ev.pairs.size()},
      {"alignment", AlignmentTypeName(ev.alignment)},
      {"reference_from_estimate", Sim3ToJson(ev.reference_from_estimate)},
      {"scale", ev.reference_from_estimate.scale},
      {"ate",
       {{"translation_m", StatsToJson(ev.ate_translation_m)},
        {"rotation_deg", StatsToJson(ev.ate_rotation_deg)}}},
      {"alignment_conditioning", ConditioningToJson(ev)},
      {"rpe",
       {{"per_frame",
         {{"translation_m", StatsToJson(ev.rpe_translation_m)},
          {"rotation_deg", StatsToJson(ev.rpe_rotation_deg)}}},
        {"distance", windows}}},
  };

  const AlignmentConditioning& conditioning = ev.alignment_conditioning;
  if (conditioning.rotation_dominated) {
    const Vec3& axis = conditioning.weak_axis;
    LogWarning(
        "evaluate: the rotation ATE ({:.4f} deg rmse) is dominated by the {} alignment: the "
        "positions fix its rotation only to {:.4f} deg (1 sigma) about the axis [{:.2f} {:.2f} "
        "{:.2f}] (a short or nearly straight path); judge rotations by the RPE or with --alignment "
        "none",
        ev.ate_rotation_deg.rmse, AlignmentTypeName(ev.alignment),
        conditioning.rotation_sigma_rad * 180.0 / M_PI, axis.x(), axis.y(), axis.z());
  }
  for (const auto& p : reference.poses())
    out.plot.reference.push_back(p.pose.translation());
  for (const auto& p : estimate.poses()) {
    out.plot.estimate.push_back(ev.reference_from_estimate *
                                p.pose.translation());
  }
  for (size_t k = 0; k < ev.t_ns.size(); ++k) {
    out.plot.error_time_s.push_back(
        NsToSeconds(ev.t_ns[k] - reference.start_ns()));
  }
  out.plot.error_m = ev.translation_errors_m;
  out.plot.title = fmt::format("ATE ({}) rmse {:.4f} m, {} poses",
                               AlignmentTypeName(ev.alignment),
                               ev.ate_translation_m.rmse,
                               ev.pairs.size());
  out.summary = fmt::format(
      "{} of {} reference poses associated; ATE rmse {:.4f} m (max {:.4f} m)",
      ev.pairs.size(),
      ev.num_reference,
      ev.ate_translation_m.rmse,
      ev.ate_translation_m.max);
  if (ev.alignment == AlignmentType::kSim3) {
    out.summary +=
        fmt::format(", Sim(3) scale {:.6f}", ev.reference_from_estimate.scale);
  }
  return out;
}

Outputs EvaluateAgainstControlPoints(const std::string& reference_path,
                                     const std::string& estimate_path,
                                     const Trajectory& estimate,
                                     const HiltiScoreOptions& options) {
  const std::vector<ControlPoint> control_points =
      ReadControlPoints(reference_path);
  HiltiScore score;
  try {
    score = ComputeHiltiScore(control_points, estimate, options);
  } catch (const InputError& e) {
    RethrowWithFiles(e, reference_path, estimate_path);
  }

  std::string table = fmt::format(
      "control points {} ({} points)\nestimate  {} ({} poses)\nassociated {} "
      "points within {} s, "
      "SE(3) alignment of the pole tip (lever arm {:g} {:g} {:g} m)\n\n",
      reference_path,
      control_points.size(),
      estimate_path,
      estimate.size(),
      score.num_associated,
      NsToSeconds(options.max_dt_ns),
      options.tip_in_imu.x(),
      options.tip_in_imu.y(),
      options.tip_in_imu.z());
  table += fmt::format("{:>4}  {:<22}{:>10}{:>12}{:>8}\n",
                       "#",
                       "t [s]",
                       "dt [s]",
                       "error [m]",
                       "points");
  json points = json::array();
  for (size_t i = 0; i < score.points.size(); ++i) {
    const ControlPointResult& p = score.points[i];
    const std::string t = FormatNsAsSeconds(p.control_point.t_ns);
    if (p.associated) {
      table += fmt::format("{:>4}  {:<22}{:>10.3f}{:>12.4f}{:>8}\n",
                           i + 1,
                           t,
                           NsToSeconds(p.dt_ns),
                           p.error_m,
                           p.points);
    } else {
      table += fmt::format(
          "{:>4}  {:<22}{:>10}{:>12}{:>8}\n", i + 1, t, "-", "missing", 0);
    }
    const Vec3& c = p.control_point.position;
    json entry = {{"t_s", t},
                  {"id", p.control_point.id},
                  {"position_m", {c.x(), c.y(), c.z()}},
                  {"associated", p.associated},
                  {"points", p.points}};
    if (p.associated) {
      entry["dt_s"] = NsToSeconds(p.dt_ns);
      entry["error_m"] = p.error_m;
      entry["aligned_tip_m"] = {
          p.aligned_tip.x(), p.aligned_tip.y(), p.aligned_tip.z()};
    }
    points.push_back(entry);
  }
  table += fmt::format(
      "\nHILTI 2022 score {:.2f} / 100 ({} of {} points associated)\n",
      score.score,
      score.num_associated,
      control_points.size());
  table += StatsHeader() + "\n" + StatsRow("tip error [m]", score.errors_m);
  std::cout << table;

  Outputs out;
  out.metrics = {
      {"reference_type", "control_points"},
      {"num_control_points", control_points.size()},
      {"num_estimate_poses", estimate.size()},
      {"num_associated", score.num_associated},
      {"alignment", "se3"},
      {"reference_from_estimate", Sim3ToJson(score.reference_from_estimate)},
      {"ate", {{"translation_m", StatsToJson(score.errors_m)}}},
      {"hilti2022",
       {{"score", score.score},
        {"tip_in_imu_m",
         {options.tip_in_imu.x(),
          options.tip_in_imu.y(),
          options.tip_in_imu.z()}},
        {"thresholds_m", options.thresholds_m},
        {"band_points", options.band_points},
        {"points", points}}},
  };

  for (const auto& c : control_points) out.plot.reference.push_back(c.position);
  out.plot.reference_as_markers = true;
  out.plot.reference_label = "control points";
  out.plot.estimate_label = "estimated pole tip (aligned)";
  for (const auto& p : estimate.poses()) {
    out.plot.estimate.push_back(score.reference_from_estimate *
                                (p.pose * options.tip_in_imu));
  }
  const TimestampNs t0 = control_points.front().t_ns;
  for (const auto& p : score.points) {
    if (!p.associated) continue;
    out.plot.error_time_s.push_back(NsToSeconds(p.control_point.t_ns - t0));
    out.plot.error_m.push_back(p.error_m);
  }
  out.plot.title =
      fmt::format("HILTI 2022 score {:.2f} / 100, {} of {} control points",
                  score.score,
                  score.num_associated,
                  control_points.size());
  out.summary = fmt::format(
      "{} of {} control points associated; HILTI 2022 score {:.2f} / 100; "
      "tip error rmse {:.4f} m",
      score.num_associated,
      control_points.size(),
      score.score,
      score.errors_m.rmse);
  return out;
}

}  // namespace

int RunEvaluate(int argc, char** argv) {
  const auto start = std::chrono::steady_clock::now();
  OptionManager options(
      "lisfm evaluate",
      "score a trajectory against ground truth (ATE, RPE, HILTI 2022 score)");
  std::string reference_path;
  std::string estimate_path;
  double max_dt_s = kDefaultTrajectoryMaxDtS;
  std::string reference_type = "trajectory";
  std::string output_path;
  TrajectoryEvaluationOptions eval;
  HiltiScoreOptions hilti;
  bool overwrite = false;
  options.AddRequiredString(
      "reference_path",
      &reference_path,
      "reference: TUM .txt / EuRoC .csv trajectory or HILTI control points");
  options.AddAlias("reference", "reference_path");
  options.AddRequiredString(
      "estimate_path",
      &estimate_path,
      "estimated trajectory (TUM .txt or EuRoC .csv, IMU frame)");
  options.AddAlias("estimate", "estimate_path");
  AddTrajectoryEvaluationOptions(&options, &eval);
  options.AddDouble(
      "max_dt",
      &max_dt_s,
      "association tolerance in s (default 0.01 for trajectories, 2 for "
      "control points)",
      OptionRange::AtLeast(0));
  options.AddChoice("reference_type",
                    &reference_type,
                    {"trajectory", "control_points"},
                    "what --reference_path holds");
  options.AddString(
      "output_path",
      &output_path,
      "folder for metrics.json and evaluation.png (created; optional)");
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  if (!options.Parse(argc, argv)) return 0;
  std::optional<OutputFolder> output;  // checked before the work
  if (!output_path.empty()) output.emplace(output_path, overwrite);

  const bool control_points = reference_type == "control_points";
  if (control_points && !options.IsSet("max_dt"))
    max_dt_s = kDefaultControlPointMaxDtS;
  if (!IsRepresentableAsNs(max_dt_s)) {
    throw UsageError(fmt::format(
        "--max_dt {} is out of range: must be < {:.0f} s", max_dt_s, kMaxAbsSecondsAsNs));
  }
  if (control_points && eval.alignment != AlignmentType::kSE3) {
    LogWarning(
        "the HILTI 2022 score always uses SE(3) alignment without scale; "
        "--alignment {} ignored",
        AlignmentTypeName(eval.alignment));
  }

  LogStage("evaluate");
  CheckFileExists(reference_path,
                  control_points ? "control point file" : "reference file");
  const Trajectory estimate = ReadTrajectory(estimate_path);
  const int64_t max_dt_ns = SecondsToNs(max_dt_s);

  Outputs out;
  if (control_points) {
    hilti.max_dt_ns = max_dt_ns;
    options.ThrowUnlessValid(hilti.Check());
    out = EvaluateAgainstControlPoints(
        reference_path, estimate_path, estimate, hilti);
  } else {
    eval.max_dt_ns = max_dt_ns;
    options.ThrowUnlessValid(eval.Check());
    out = EvaluateAgainstTrajectory(
        reference_path, estimate_path, estimate, eval);
  }

  std::string written;
  if (output) {
    out.metrics["reference"] = reference_path;
    out.metrics["estimate"] = estimate_path;
    out.metrics["max_dt_s"] = max_dt_s;
    WriteFileAtomically(output->File("metrics.json"), out.metrics.dump(2) + "\n");
    WriteTrajectoryPlot(output->File("evaluation.png"), out.plot);
    options.WriteConfig(output->File("evaluate_config.yaml"));
    output->Commit();
    written = fmt::format("; wrote {}, {} and {}",
                          JoinPaths(output_path, "metrics.json"),
                          JoinPaths(output_path, "evaluation.png"),
                          JoinPaths(output_path, "evaluate_config.yaml"));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
          .count();
  LogInfo("evaluate summary: {} in {:.2f} s{}", out.summary, seconds, written);
  return 0;
}

}  // namespace lisfm
