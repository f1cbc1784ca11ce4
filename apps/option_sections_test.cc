// The ranges registered by apps/option_sections.cc agree with the options
// structs' Check(): for every registered numeric option with a range, a value
// just outside each bound makes Check() fail on exactly that field, and the
// value at the bound (inside) passes.
#include "apps/option_sections.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <set>
#include <string>

#include "core/errors.h"
#include "core/option_check.h"

namespace lisfm {
namespace {

std::string ValueText(double v, bool integer) {
  char buf[64];
  if (integer) {
    std::snprintf(buf, sizeof(buf), "%lld", static_cast<long long>(v));
  } else {
    std::snprintf(buf, sizeof(buf), "%.17g", v);
  }
  return buf;
}

const OptionInfo* FindOption(const std::vector<OptionInfo>& infos,
                             const std::string& name) {
  for (const OptionInfo& info : infos) {
    if (info.name == name) return &info;
  }
  return nullptr;
}

// Options whose bound is only reachable together with another option
// (OptionManager::RequireLess): at their lower bound the relation fails.
const std::set<std::string> kRelationBound = {
    "Bayesian.num_iterations", "Lio.max_range", "Map.voxel_size", "Fusion.max_depth_m"};

// The values at the bounds, just inside (inclusive: the bound; exclusive: the
// next integer / double inside).
std::vector<double> InsideBoundaryValues(const OptionRange& range,
                                         bool integer) {
  std::vector<double> inside;
  for (const double outside : range.OutsideValues(integer)) {
    const double up = integer ? outside + 1 : std::nextafter(outside, HUGE_VAL);
    const double down =
        integer ? outside - 1 : std::nextafter(outside, -HUGE_VAL);
    if (range.Contains(up)) inside.push_back(up);
    if (range.Contains(down)) inside.push_back(down);
  }
  return inside;
}

template <typename Options>
void ExpectRangesAgreeWithCheck(
    const std::function<void(OptionManager*, Options*)>& add) {
  Options defaults;
  OptionManager probe("lisfm test", "ranges");
  add(&probe, &defaults);
  ASSERT_TRUE(defaults.Check()) << LastOptionCheckFailure().ToString();
  size_t num_ranged = 0;
  for (const OptionInfo& info : probe.Options()) {
    if (!info.numeric || !info.range.IsBounded()) continue;
    ++num_ranged;
    for (const double v : info.range.OutsideValues(info.integer)) {
      Options o;
      OptionManager options("lisfm test", "ranges");
      add(&options, &o);
      const std::string text = ValueText(v, info.integer);
      try {
        options.Set(info.name, text);
      } catch (const UsageError&) {
        EXPECT_LT(v, 0)
            << info.name;  // an unsigned field: the parser rejects it
        continue;
      }
      EXPECT_FALSE(o.Check())
          << "--" << info.name << " " << text << " passes Check()";
      EXPECT_EQ(LastOptionCheckFailure().field,
                FindOption(options.Options(), info.name)->field)
          << "--" << info.name << " " << text << ": Check() failed on "
          << LastOptionCheckFailure().ToString();
    }
    if (kRelationBound.count(info.name) > 0) continue;
    for (const double v : InsideBoundaryValues(info.range, info.integer)) {
      Options o;
      OptionManager options("lisfm test", "ranges");
      add(&options, &o);
      const std::string text = ValueText(v, info.integer);
      options.Set(info.name, text);
      EXPECT_TRUE(o.Check())
          << "--" << info.name << " " << text << " is in range "
          << info.range.ToString()
          << " but fails Check(): " << LastOptionCheckFailure().ToString();
    }
  }
  EXPECT_GT(num_ranged, 0u);
}

TEST(OptionSections, IcpRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<IcpOptions>(AddIcpOptions);
  ExpectRangesAgreeWithCheck<NormalOptions>(AddNormalOptions);
  ExpectRangesAgreeWithCheck<SgldOptions>(AddSgldOptions);
  ExpectRangesAgreeWithCheck<BayesianIcpOptions>(AddBayesianIcpOptions);
}

TEST(OptionSections, FusionRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<ProjectiveIcpOptions>(AddProjectiveIcpOptions);
  ExpectRangesAgreeWithCheck<SurfelFusionOptions>(AddSurfelFusionOptions);
  ExpectRangesAgreeWithCheck<RgbdFusionOptions>(AddRgbdFusionOptions);
}

TEST(OptionSections, DatabaseImporterRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<DatabaseImporterOptions>(AddDatabaseImporterOptions);
}

TEST(OptionSections, LioRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<LioOptions>(AddLioOptions);
  ExpectRangesAgreeWithCheck<VoxelMapOptions>(AddVoxelMapOptions);
  ExpectRangesAgreeWithCheck<ImuInitializerOptions>(AddImuInitializerOptions);
}

TEST(OptionSections, PoseGraphRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<PoseGraphSolverOptions>(AddPoseGraphSolverOptions);
  ExpectRangesAgreeWithCheck<G2oOptimizationOptions>(AddPoseGraphOptions);
}

TEST(OptionSections, SimulatorRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<sim::SimulatorOptions>(
      [](OptionManager* options, sim::SimulatorOptions* sim) {
        sim->output_path = "out";  // required
        AddSimulatorOptions(options, sim);
      });
  ExpectRangesAgreeWithCheck<sim::CalibrationErrorOptions>(AddCalibrationErrorOptions);
  ExpectRangesAgreeWithCheck<sim::ImuErrorOptions>(AddImuErrorOptions);
}

TEST(OptionSections, GlobalMapperRangesAgreeWithCheck) {
  ExpectRangesAgreeWithCheck<colmap::GlobalMapperOptions>(
      AddGlobalMapperOptions);
  ExpectRangesAgreeWithCheck<colmap::LoadMapperStateOptions>(
      AddLoadMapperStateOptions);
  ExpectRangesAgreeWithCheck<colmap::ViewGraphOptions>(AddViewGraphOptions);
  ExpectRangesAgreeWithCheck<colmap::RotationAveragingOptions>(
      AddRotationAveragingOptions);
  ExpectRangesAgreeWithCheck<colmap::TranslationAveragingOptions>(
      AddTranslationAveragingOptions);
  ExpectRangesAgreeWithCheck<colmap::TrackOptions>(AddTrackOptions);
  ExpectRangesAgreeWithCheck<colmap::TriangulationOptions>(
      AddTriangulationOptions);
  ExpectRangesAgreeWithCheck<colmap::BundleAdjustmentOptions>(
      AddBundleAdjustmentOptions);
}

TEST(OptionSections, EvaluationAlignmentAndAlias) {
  TrajectoryEvaluationOptions eval;
  OptionManager options("lisfm evaluate", "test");
  AddTrajectoryEvaluationOptions(&options, &eval);
  options.Set("align", "sim3");
  EXPECT_EQ(eval.alignment, AlignmentType::kSim3);
  colmap::SfmEvaluationOptions sfm;
  OptionManager sfm_options("lisfm model_evaluator", "test");
  AddSfmEvaluationOptions(&sfm_options, &sfm);
  sfm_options.Set("alignment", "none");
  EXPECT_EQ(sfm.alignment, AlignmentType::kNone);
}

// A single command (the coming `lisfm pipeline`) can register the stages'
// options side by side: no two sections claim the same name.
TEST(OptionSections, StagesFitInOneCommand) {
  IcpOptions icp;
  NormalOptions normals;
  BayesianIcpOptions bayes;
  LioOptions lio;
  TrajectoryEvaluationOptions eval;
  colmap::GlobalMapperOptions mapper;
  OptionManager options("lisfm pipeline", "test");
  AddIcpOptions(&options, &icp);
  AddNormalOptions(&options, &normals);
  AddBayesianIcpOptions(&options, &bayes);
  AddLioOptions(&options, &lio);
  AddTrajectoryEvaluationOptions(&options, &eval);
  EXPECT_NO_THROW(AddGlobalMapperOptions(&options, &mapper));
}

}  // namespace
}  // namespace lisfm
