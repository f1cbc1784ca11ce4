// `lisfm icp`: registers a source cloud to a target cloud (PCD/PLY) with
// point-to-plane ICP or Bayesian ICP and prints T_target_source, its 6x6
// covariance (right perturbation, xi = [omega; v]), inliers, RMSE and timings.
#include <algorithm>
#include <chrono>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include <fmt/format.h>
#include <tbb/parallel_invoke.h>

#include "apps/commands.h"
#include "apps/option_sections.h"
#include "core/errors.h"
#include "core/file_utils.h"
#include "core/io/cloud_io.h"
#include "core/logging.h"
#include "core/options.h"
#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "icp/icp_covariance.h"

namespace lisfm {

namespace {

double Seconds(std::chrono::steady_clock::time_point a) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
}

// A 4x4 matrix as 16 numbers (rows), the format of registration_lidar_pair/relative.txt.
SE3 ReadTransform(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "cannot open the initial transform file");
  Mat4 m;
  for (int i = 0; i < 16; ++i) {
    if (!(in >> m(i / 4, i % 4))) {
      throw InputError(path, fmt::format("value {}", i + 1),
                       "expected 16 numbers (a 4x4 matrix, row by row), found fewer or a non-number");
    }
  }
  const Mat3 R = m.topLeftCorner<3, 3>();
  if (!m.allFinite() || (R.transpose() * R - Mat3::Identity()).norm() > 1e-3 ||
      R.determinant() < 0) {
    throw InputError(path, "rotation block", "expected a rotation matrix (orthonormal, det +1)");
  }
  const Eigen::JacobiSVD<Mat3> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return SE3(Mat3(svd.matrixU() * svd.matrixV().transpose()), Vec3(m.topRightCorner<3, 1>()));
}

std::string FormatMatrix(const Eigen::MatrixXd& m, int precision) {
  std::ostringstream s;
  s << std::setprecision(precision);
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) s << (c ? " " : "") << m(r, c);
    s << "\n";
  }
  return s.str();
}

PointSet LoadPoints(const std::string& path) {
  size_t dropped = 0;
  PointSet pts = ReadPointPositions(path, &dropped);
  if (dropped > 0) LogInfo("{}: dropped {} non-finite points", path, dropped);
  if (pts.size() < 6) {
    throw InputError(path, "", fmt::format("expected at least 6 finite points, found {}", pts.size()));
  }
  return pts;
}

}  // namespace

int RunIcp(int argc, char** argv) {
  OptionManager options("lisfm icp", "register a source cloud to a target cloud (PCD/PLY)");
  std::string source_path, target_path, init_path, output_path, method = "point_to_plane";
  double source_voxel_m = 0.25, target_voxel_m = 0.1;
  NormalOptions normal_options;
  IcpOptions icp;
  BayesianIcpOptions bayes;  // its association (kernel, normals) defaults differ: see below
  bool overwrite = false;
  options.AddRequiredString("source_path", &source_path, "source cloud (.pcd/.ply)");
  options.AddRequiredString("target_path", &target_path, "target cloud (.pcd/.ply)");
  options.AddString("init_path", &init_path,
                    "initial T_target_source: 4x4 matrix, 16 numbers row by row (default identity)");
  options.AddChoice("method", &method, {"point_to_plane", "bayesian"}, "registration method");
  options.AddString("output_path", &output_path,
                    "folder for T_target_source.txt, covariance.txt, result.yaml and config.yaml (optional)");
  options.AddDouble("Icp.source_voxel_size", &source_voxel_m,
                    "source voxel downsampling (m, 0 = off)", OptionRange::AtLeast(0));
  options.AddDouble("Icp.target_voxel_size", &target_voxel_m,
                    "target voxel downsampling (m, 0 = off)", OptionRange::AtLeast(0));
  AddNormalOptions(&options, &normal_options);
  AddIcpOptions(&options, &icp);
  AddBayesianIcpOptions(&options, &bayes);
  options.AddBool("overwrite", &overwrite, "replace an earlier lisfm output at --output_path");
  if (!options.Parse(argc, argv)) return 0;
  std::optional<OutputFolder> output;  // checked before the work
  if (!output_path.empty()) output.emplace(output_path, overwrite);
  NormalOptions target_normals = normal_options;
  if (method == "bayesian") {
    // The calibrated association of Bayesian ICP (BayesianIcpOptions): the Icp.*
    // options except kernel, kernel scale, planarity and normal-contrast gates, the
    // view gates and normal k, which come from Bayesian.*.
    const IcpOptions calibrated = bayes.icp;
    bayes.icp = icp;
    bayes.icp.kernel = calibrated.kernel;
    bayes.icp.kernel_scale_m = calibrated.kernel_scale_m;
    bayes.icp.min_planarity = calibrated.min_planarity;
    bayes.icp.field_of_view_gate = calibrated.field_of_view_gate;
    bayes.icp.visibility_gate_m = calibrated.visibility_gate_m;
    bayes.icp.visibility_follows_surface = calibrated.visibility_follows_surface;
    bayes.icp.min_normal_contrast = calibrated.min_normal_contrast;
    target_normals.num_neighbors = bayes.normal_neighbors;
  }
  // Parse validated each struct as registered; these hold after the merge too.
  options.ThrowUnlessValid(target_normals.Check());
  if (method == "bayesian") options.ThrowUnlessValid(bayes.Check());

  const SE3 initial = init_path.empty() ? SE3() : ReadTransform(init_path);
  // The source chain (load, voxel grid) and the target chain (load, voxel
  // grid, KD-tree) are independent: one task each, so both cores work.
  // Loads one cloud and times it: (points after voxel downsampling, count before).
  struct Chain {
    size_t full_size = 0;
    double load_s = 0.0, prep_s = 0.0;
    PointSet Run(const std::string& path, double voxel_m) {
      const auto t0 = std::chrono::steady_clock::now();
      const PointSet full = LoadPoints(path);
      full_size = full.size();
      load_s = Seconds(t0);
      const auto t1 = std::chrono::steady_clock::now();
      PointSet out = VoxelDownsamplePoints(full, voxel_m);
      prep_s = Seconds(t1);
      return out;
    }
  };
  Chain source_chain, target_chain;
  PointSet source;
  std::unique_ptr<KdTreeTarget> target_ptr;
  tbb::parallel_invoke(
      [&] { source = source_chain.Run(source_path, source_voxel_m); },
      [&] {
        PointSet points = target_chain.Run(target_path, target_voxel_m);
        const auto t0 = std::chrono::steady_clock::now();
        target_ptr = std::make_unique<KdTreeTarget>(std::move(points), target_normals);
        target_chain.prep_s += Seconds(t0);
      });
  const KdTreeTarget& target = *target_ptr;
  const double load_s = std::max(source_chain.load_s, target_chain.load_s);
  const double prep_s = std::max(source_chain.prep_s, target_chain.prep_s);
  const auto t2 = std::chrono::steady_clock::now();
  IcpResult result;
  Mat6 covariance;
  std::string covariance_kind;
  if (method == "bayesian") {
    const BayesianIcpResult b = RegisterBayesian(source, target, initial, bayes);
    result = b.icp;
    result.target_from_source = b.posterior.mean;
    covariance = b.posterior.covariance;
    covariance_kind = fmt::format("Bayesian ICP posterior ({} SGLD samples)", b.posterior.num_samples);
  } else {
    result = RegisterPointToPlane(source, target, initial, icp);
    covariance = ClosedFormCovariance(result);
    covariance_kind = "closed form sigma^2 H^-1";
  }
  const double reg_s = Seconds(t2);

  const std::string transform_text = FormatMatrix(result.target_from_source.Matrix(), 10);
  const std::string covariance_text = FormatMatrix(covariance, 6);
  std::cout << "T_target_source:\n" << transform_text << "covariance (" << covariance_kind
            << ", xi = [omega; v], rad/m):\n" << covariance_text
            << fmt::format("converged: {}\ndegenerate: {}\niterations: {}\ninliers: {}\nrmse_m: {:.6f}\n"
                           "time_s: load {:.3f} preprocess {:.3f} (source and target in "
                           "parallel; the longer of the two) registration {:.3f}\n",
                           result.converged, result.degenerate, result.iterations,
                           result.num_inliers, result.rmse_m, load_s, prep_s, reg_s);
  // Not converged is a result, not an error: exit 0, but say so loudly.
  if (!result.converged) {
    std::cout << "WARNING: not converged: " << result.message << "\n";
  }
  std::cout.flush();
  if (output) {
    WriteFileAtomically(output->File("T_target_source.txt"), transform_text);
    WriteFileAtomically(output->File("covariance.txt"), covariance_text);
    WriteFileAtomically(
        output->File("result.yaml"),
        fmt::format("method: {}\nconverged: {}\ndegenerate: {}\niterations: {}\ninliers: {}\n"
                    "rmse_m: {:.9g}\ncovariance: \"{}\"\nmessage: \"{}\"\n",
                    method, result.converged, result.degenerate, result.iterations,
                    result.num_inliers, result.rmse_m, covariance_kind, result.message));
    options.WriteConfig(output->File("config.yaml"));
    output->Commit();
  }
  LogInfo("icp ({}): {} source / {} target points after downsampling ({} / {} loaded), {} "
          "inliers, RMSE {:.4f} m, {} iterations, {}{}; load {:.3f} s, preprocess {:.3f} s, "
          "registration {:.3f} s{}",
          method, source.size(), target.size(), source_chain.full_size, target_chain.full_size,
          result.num_inliers, result.rmse_m, result.iterations,
          result.converged ? "converged" : "NOT converged: ", result.converged ? "" : result.message,
          load_s, prep_s, reg_s,
          output_path.empty() ? "" : "; wrote " + output_path + "/{T_target_source,covariance}.txt, result.yaml");
  if (!result.converged) LogWarning("icp: {}", result.message);
  return 0;
}

}  // namespace lisfm
