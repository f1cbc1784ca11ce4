// Side-by-side ICP benchmark on the real pairs of ../shared/data (scripts/bench_icp.sh):
// lisfm point-to-plane (and Bayesian ICP, closed-form covariance) vs PCL
// IterativeClosestPointWithNormals, PCL GeneralizedIterativeClosestPoint and Open3D
// point-to-plane. Each method runs its whole process (load, voxel downsampling,
// normals, registration) with its own library's functions and the same parameters.
// Ours runs its two independent chains (source: load, voxel grid; target: load,
// voxel grid, tree) as two TBB tasks, one per core; the stage table (`--stages`)
// times the stages one after the other.
// `--knn` compares lisfm's KD-tree with nanoflann and FLANN (exact, one thread).
//
// Times are medians over `repeats` rounds (whole process and registration alone), each
// round running every method once (interleaved); the errors are of the last round. The
// Bayesian time is ICP + SGLD from the same (lazily normal-estimated) target.
// `--stages` first prints the stage timings of ours (load, voxel grids, tree,
// registration, iterations).
// `--only_lisfm` runs only our point-to-plane (quick accuracy/timing checks).
// `--ab NAME=VALUE` compares our whole process with one IcpOptions field changed
// (coarse_min_points or coarse_levels) against the library defaults, alternating the
// two (and which goes first) in each repeat (one process, so that load drifts hit
// both alike), and exits.
// `--bayes_no_view_gates` (alias `--bayes_previous`) also runs Bayesian ICP without the
// view gates and with the CR1 sandwich (accuracy side by side with the default).
// Usage: lisfm_icp_bench DATA_DIR [repeats] [--knn] [--stages] [--only_lisfm] [--ab NAME=VALUE]
//        [--bayes_no_view_gates]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <flann/flann.hpp>
#include <nanoflann.hpp>
#include <open3d/geometry/PointCloud.h>
#include <open3d/io/PointCloudIO.h>
#include <open3d/utility/Logging.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>
#include <tbb/parallel_invoke.h>

#include "core/io/cloud_io.h"
#include "core/io/cloud_io_pcl.h"
#include "icp/bayesian_icp.h"
#include "icp/icp.h"
#include "icp/icp_covariance.h"

namespace lisfm {
namespace {

using Clock = std::chrono::steady_clock;
double Ms(Clock::time_point a) {
  return std::chrono::duration<double, std::milli>(Clock::now() - a).count();
}

struct Pair {
  std::string name, source, target;
  Mat4 reference = Mat4::Identity();  // T_target_source
  double source_voxel = 0, target_voxel = 0, max_distance = 1.0, kernel_scale = 0.1;
  int normal_k = 10;
};

struct Outcome {
  double ms = 0;      // whole process: load, downsampling, normals, registration
  double reg_ms = 0;  // registration alone (for lisfm: including lazy target normals)
  Mat4 T = Mat4::Identity();
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void Errors(const Mat4& T, const Mat4& ref, double* rot_deg, double* trans_m) {
  const Mat3 dR = T.topLeftCorner<3, 3>().transpose() * ref.topLeftCorner<3, 3>();
  *rot_deg = Eigen::AngleAxisd(Mat3(dR)).angle() * 180.0 / M_PI;
  *trans_m = (T.topRightCorner<3, 1>() - ref.topRightCorner<3, 1>()).norm();
}

// --bayes_no_view_gates: Bayesian ICP also without the view gates, with the CR1 sandwich
// and noise_sigma_scale 1.262 (the scale fitted for that model), for the accuracy side
// by side.
bool g_bayes_no_view_gates = false;

Outcome RunOurs(const Pair& p, bool bayesian, double* bayes_ms, double* closed_ms,
               const IcpOptions& base = IcpOptions()) {
  const auto t0 = Clock::now();
  // The source chain (load, voxel grid) and the target chain (load, voxel grid,
  // tree) are independent: one task each, so that both cores work (the
  // registration itself is parallel too).
  PointSet src, tgt_points;
  const NormalOptions normal_options{p.normal_k, 10 * std::max(p.target_voxel, 0.01)};
  std::unique_ptr<KdTreeTarget> tgt_ptr;
  tbb::parallel_invoke(
      [&] { src = VoxelDownsamplePoints(ReadPointPositions(p.source), p.source_voxel); },
      [&] {
        tgt_points = VoxelDownsamplePoints(ReadPointPositions(p.target), p.target_voxel);
        tgt_ptr = std::make_unique<KdTreeTarget>(tgt_points, normal_options);
      });
  const KdTreeTarget& tgt = *tgt_ptr;
  IcpOptions o = base;
  o.max_correspondence_distance_m = p.max_distance;
  o.kernel_scale_m = p.kernel_scale;
  const auto t_reg = Clock::now();
  const IcpResult r = RegisterPointToPlane(src, tgt, SE3(), o);
  Outcome out;
  out.reg_ms = Ms(t_reg);
  out.ms = Ms(t0);
  out.T = r.target_from_source.Matrix();
  const auto t1 = Clock::now();
  const Mat6 c = ClosedFormCovariance(r);
  *closed_ms = Ms(t1);
  if (!c.allFinite()) std::printf("non-finite closed form\n");
  if (bayesian) {
    // Bayesian ICP with its own (calibrated) association: the library's kernel,
    // planarity gate and normal k, the kernel scale in the same proportion to the pair's ICP scale
    // (LiDAR pairs: 0.05 m; bunny 2.5 mm).
    BayesianIcpOptions b;
    if (g_bayes_no_view_gates) {
      b.icp.field_of_view_gate = false;
      b.icp.visibility_gate_m = 0;
      b.jackknife_leverage_power = 0;
      b.noise_sigma_scale = 1.262;
    }
    const double kernel_ratio = b.icp.kernel_scale_m / IcpOptions().kernel_scale_m;
    b.icp.max_correspondence_distance_m = p.max_distance;
    b.icp.kernel_scale_m = kernel_ratio * p.kernel_scale;
    const NormalOptions bayes_normals{b.normal_neighbors, normal_options.max_radius_m};
    // A fresh target (tree + lazy normals) so that the time includes them.
    const auto t2 = Clock::now();
    const KdTreeTarget fresh(tgt_points, bayes_normals);
    const BayesianIcpResult br = RegisterBayesian(src, fresh, SE3(), b);
    *bayes_ms = Ms(t2);
    double rot_deg = 0, trans_m = 0;
    Errors(br.posterior.mean.Matrix(), p.reference, &rot_deg, &trans_m);
    std::printf("    bayesian%s (%s %.3f m, k = %d, planarity >= %.2f): posterior-mean error %.3f deg / %.4f m; %zu source / %zu target pts, %zu SGLD samples, %zu re-associations, std rot %.3f/%.3f/%.3f mrad, trans %.2f/%.2f/%.2f mm; closed form trans %.2f/%.2f/%.2f mm\n",
                g_bayes_no_view_gates ? ", no view gates, CR1, 1.262" : "", b.icp.kernel.c_str(),
                b.icp.kernel_scale_m, b.normal_neighbors, b.icp.min_planarity,
                rot_deg, trans_m,
                src.size(), tgt_points.size(), br.posterior.num_samples,
                br.posterior.num_term_evaluations, 1e3 * std::sqrt(br.posterior.covariance(0, 0)),
                1e3 * std::sqrt(br.posterior.covariance(1, 1)), 1e3 * std::sqrt(br.posterior.covariance(2, 2)),
                1e3 * std::sqrt(br.posterior.covariance(3, 3)), 1e3 * std::sqrt(br.posterior.covariance(4, 4)),
                1e3 * std::sqrt(br.posterior.covariance(5, 5)), 1e3 * std::sqrt(c(3, 3)),
                1e3 * std::sqrt(c(4, 4)), 1e3 * std::sqrt(c(5, 5)));
  }
  return out;
}

// Stage timings of our whole process (ms, median over `repeats`), printed with
// `--stages`: where the time goes.
void OurStages(const Pair& p, int repeats) {
  std::vector<double> load, load_pcl, voxel, tree, reg;
  IcpResult r;
  size_t n_src = 0, n_tgt = 0, n_normals = 0;
  for (int k = 0; k < repeats; ++k) {
    auto t = Clock::now();
    const PointSet src_raw = ReadPointPositions(p.source);
    const PointSet tgt_raw = ReadPointPositions(p.target);
    load.push_back(Ms(t));
    t = Clock::now();
    if (p.source.size() > 4 && p.source.substr(p.source.size() - 4) == ".pcd") {
      ReadPcdWithPclReader(p.source);
      ReadPcdWithPclReader(p.target);
    }
    load_pcl.push_back(Ms(t));
    t = Clock::now();
    const PointSet src = VoxelDownsamplePoints(src_raw, p.source_voxel);
    const PointSet tgt_points = VoxelDownsamplePoints(tgt_raw, p.target_voxel);
    voxel.push_back(Ms(t));
    t = Clock::now();
    const NormalOptions normal_options{p.normal_k, 10 * std::max(p.target_voxel, 0.01)};
    const KdTreeTarget tgt(tgt_points, normal_options);
    tree.push_back(Ms(t));
    IcpOptions o;
    o.max_correspondence_distance_m = p.max_distance;
    o.kernel_scale_m = p.kernel_scale;
    t = Clock::now();
    r = RegisterPointToPlane(src, tgt, SE3(), o);
    reg.push_back(Ms(t));
    n_src = src.size();
    n_tgt = tgt_points.size();
    n_normals = tgt.NumNormalsEstimated();
  }
  std::printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f | %d | %zu / %zu / %zu |\n", p.name.c_str(),
              Median(load), Median(load_pcl), Median(voxel), Median(tree), Median(reg), r.iterations,
              n_src, n_tgt, n_normals);
}

template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr PclLoad(const std::string& path, double voxel) {
  typename pcl::PointCloud<PointT>::Ptr cloud(new pcl::PointCloud<PointT>);
  pcl::io::loadPCDFile(path, *cloud);
  std::vector<int> idx;
  pcl::removeNaNFromPointCloud(*cloud, *cloud, idx);
  if (voxel <= 0) return cloud;
  typename pcl::PointCloud<PointT>::Ptr out(new pcl::PointCloud<PointT>);
  pcl::VoxelGrid<PointT> grid;
  grid.setLeafSize(voxel, voxel, voxel);
  grid.setInputCloud(cloud);
  grid.filter(*out);
  return out;
}

pcl::PointCloud<pcl::PointNormal>::Ptr PclWithNormals(const std::string& path, double voxel, int k) {
  const auto xyz = PclLoad<pcl::PointXYZ>(path, voxel);
  pcl::PointCloud<pcl::Normal> normals;
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(2);
  ne.setInputCloud(xyz);
  ne.setKSearch(k);
  ne.compute(normals);
  pcl::PointCloud<pcl::PointNormal>::Ptr out(new pcl::PointCloud<pcl::PointNormal>);
  pcl::concatenateFields(*xyz, normals, *out);
  std::vector<int> idx;
  pcl::removeNaNNormalsFromPointCloud(*out, *out, idx);
  return out;
}

Outcome RunPclPointToPlane(const Pair& p) {
  const auto t0 = Clock::now();
  const auto src = PclWithNormals(p.source, p.source_voxel, p.normal_k);
  const auto tgt = PclWithNormals(p.target, p.target_voxel, p.normal_k);
  pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> icp;
  icp.setInputSource(src);
  icp.setInputTarget(tgt);
  icp.setMaxCorrespondenceDistance(p.max_distance);
  icp.setMaximumIterations(50);
  icp.setTransformationEpsilon(1e-8);
  pcl::PointCloud<pcl::PointNormal> aligned;
  const auto t_reg = Clock::now();
  icp.align(aligned);
  Outcome out;
  out.reg_ms = Ms(t_reg);
  out.ms = Ms(t0);
  out.T = icp.getFinalTransformation().cast<double>();
  return out;
}

Outcome RunPclGicp(const Pair& p) {
  const auto t0 = Clock::now();
  const auto src = PclLoad<pcl::PointXYZ>(p.source, p.source_voxel);
  const auto tgt = PclLoad<pcl::PointXYZ>(p.target, p.target_voxel);
  pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> gicp;
  gicp.setInputSource(src);
  gicp.setInputTarget(tgt);
  gicp.setMaxCorrespondenceDistance(p.max_distance);
  gicp.setMaximumIterations(50);
  gicp.setTransformationEpsilon(1e-8);
  pcl::PointCloud<pcl::PointXYZ> aligned;
  const auto t_reg = Clock::now();
  gicp.align(aligned);  // includes GICP's own covariance (kNN) estimation
  Outcome out;
  out.reg_ms = Ms(t_reg);
  out.ms = Ms(t0);
  out.T = gicp.getFinalTransformation().cast<double>();
  return out;
}

Outcome RunOpen3d(const Pair& p) {
  namespace reg = open3d::pipelines::registration;
  const auto t0 = Clock::now();
  auto load = [&](const std::string& path, double voxel) {
    open3d::geometry::PointCloud pc;
    open3d::io::ReadPointCloud(path, pc);
    pc.RemoveNonFinitePoints();
    auto down = voxel > 0 ? pc.VoxelDownSample(voxel) : std::make_shared<open3d::geometry::PointCloud>(pc);
    down->EstimateNormals(open3d::geometry::KDTreeSearchParamKNN(p.normal_k));
    return down;
  };
  const auto src = load(p.source, p.source_voxel);
  const auto tgt = load(p.target, p.target_voxel);
  const auto t_reg = Clock::now();
  const auto r = reg::RegistrationICP(*src, *tgt, p.max_distance, Mat4::Identity(),
                                      reg::TransformationEstimationPointToPlane(),
                                      reg::ICPConvergenceCriteria(1e-6, 1e-6, 50));
  Outcome out;
  out.reg_ms = Ms(t_reg);
  out.ms = Ms(t0);
  out.T = r.transformation_;
  return out;
}

Mat4 ReadMatrix(const std::string& path) {
  std::ifstream in(path);
  Mat4 m;
  for (int i = 0; i < 16; ++i) in >> m(i / 4, i % 4);
  return m;
}

std::vector<Mat4> ReadBalmPoses(const std::string& path) {
  std::ifstream in(path);
  std::vector<Mat4> poses;
  std::string line;
  std::vector<double> v;
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream s(line);
    double x;
    while (s >> x) v.push_back(x);
  }
  for (size_t k = 0; k + 16 <= v.size(); k += 16) {
    Mat4 m = Mat4::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = v[k + 4 * r + c];
    poses.push_back(m);
  }
  return poses;
}

// nanoflann dataset adaptor (the previous engine of KdTree, kept as a reference).
struct NanoflannAdaptor {
  const PointSet* points;
  size_t kdtree_get_point_count() const { return points->size(); }
  float kdtree_get_pt(size_t i, size_t dim) const { return (*points)[i][dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using NanoflannTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, NanoflannAdaptor>, NanoflannAdaptor, 3, uint32_t>;

// One kNN workload on the three engines (exact, one thread, leaf 16 for nanoflann
// and FLANN as measured best for them; lisfm's own leaf size is 24). `bound` > 0:
// every search is limited to that squared distance (the ICP's bounded 2-NN).
void KnnRow(const std::string& name, const PointSet& target, const PointSet& queries, int k,
            float bound) {
  std::vector<uint32_t> idx(k);
  std::vector<float> d2(k);
  auto t0 = Clock::now();
  const KdTree tree(target);
  const double ours_build = Ms(t0);
  double checksum_ours = 0;
  t0 = Clock::now();
  for (const auto& q : queries) {
    const size_t n = bound > 0 ? tree.KnnWithin(q, k, bound, idx.data(), d2.data())
                               : tree.Knn(q, k, idx.data(), d2.data());
    if (n > 0) checksum_ours += d2[n - 1] + n;
  }
  const double ours_query = Ms(t0);

  t0 = Clock::now();
  NanoflannAdaptor adaptor{&target};
  NanoflannTree nano(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  const double nano_build = Ms(t0);
  double checksum_nano = 0;
  t0 = Clock::now();
  for (const auto& q : queries) {
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(idx.data(), d2.data());
    if (bound > 0) d2[k - 1] = std::nextafter(bound, std::numeric_limits<float>::infinity());
    nano.findNeighbors(result, q.data(), nanoflann::SearchParams());
    const size_t n = result.size();
    if (n > 0) checksum_nano += d2[n - 1] + n;
  }
  const double nano_query = Ms(t0);

  flann::Matrix<float> data(const_cast<float*>(target[0].data()), target.size(), 3);
  t0 = Clock::now();
  flann::Index<flann::L2_Simple<float>> index(data, flann::KDTreeSingleIndexParams(16));
  index.buildIndex();
  const double flann_build = Ms(t0);
  std::vector<size_t> fidx(k);
  double checksum_flann = 0;
  t0 = Clock::now();
  for (const auto& q : queries) {
    flann::Matrix<float> query(const_cast<float*>(q.data()), 1, 3);
    if (bound > 0) {
      std::vector<std::vector<size_t>> ri;
      std::vector<std::vector<float>> rd;
      flann::SearchParams params(-1);
      params.max_neighbors = k;
      params.sorted = true;
      const int n = index.radiusSearch(query, ri, rd, bound, params);
      if (n > 0) checksum_flann += rd[0][n - 1] + n;
    } else {
      flann::Matrix<size_t> mi(fidx.data(), 1, k);
      flann::Matrix<float> md(d2.data(), 1, k);
      index.knnSearch(query, mi, md, k, flann::SearchParams(-1));
      checksum_flann += d2[k - 1] + k;
    }
  }
  const double flann_query = Ms(t0);
  const auto same = [&](double a) { return std::abs(a - checksum_ours) <= 1e-6 * checksum_ours; };
  std::printf("| %s, k=%d%s, %zu pts, %zu queries | %.1f / %.1f ms | %.1f / %.1f ms | %.1f / %.1f ms | %.2fx | %s |\n",
              name.c_str(), k, bound > 0 ? ", bounded" : "", target.size(), queries.size(),
              ours_build, ours_query, nano_build, nano_query, flann_build, flann_query,
              nano_query / ours_query, same(checksum_nano) && same(checksum_flann) ? "same" : "DIFFER");
}

void KnnComparison(const std::string& dir) {
  std::printf("| workload (queries on 1 thread) | lisfm build / query | nanoflann build / query | FLANN build / query | nanoflann / lisfm query | results |\n|---|---|---|---|---|---|\n");
  {
    const PointSet target = FinitePointsOf(ReadPointCloud(dir + "/registration_lidar_pair/251370668.pcd"));
    const PointSet queries = FinitePointsOf(ReadPointCloud(dir + "/registration_lidar_pair/251371071.pcd"));
    KnnRow("registration_lidar_pair raw scans", target, queries, 1, 0);
    KnnRow("registration_lidar_pair raw scans", target, queries, 10, 0);
  }
  {
    // The ICP's own workloads on a BALM pair: 10-NN at the (0.1 m voxel) target
    // points (normals) and the bounded 2-NN of the (0.25 m voxel) source points.
    const std::string scans = dir + "/lidar_balm_realworld_subset/scans/";
    const PointSet target = VoxelDownsamplePoints(FinitePointsOf(ReadPointCloud(scans + "full35.pcd")), 0.1);
    const PointSet source = VoxelDownsamplePoints(FinitePointsOf(ReadPointCloud(scans + "full36.pcd")), 0.25);
    KnnRow("balm full35 target normals", target, target, 10, 0);
    KnnRow("balm full36 source -> full35", target, source, 2, 0.09f);
  }
}

}  // namespace
}  // namespace lisfm

int main(int argc, char** argv) {
  using namespace lisfm;
  if (argc < 2) {
    std::fprintf(stderr, "usage: lisfm_icp_bench DATA_DIR [repeats] [--knn] [--stages] [--only_lisfm] "
                         "[--ab NAME=VALUE] [--bayes_no_view_gates]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const int repeats = argc > 2 && argv[2][0] != '-' ? std::stoi(argv[2]) : 3;
  bool knn = false, stages = false, only_lisfm = false, bayes_no_view_gates = false;
  std::string ab;
  for (int i = 2; i < argc; ++i) {
    if (std::string(argv[i]) == "--ab" && i + 1 < argc) ab = argv[i + 1];
    only_lisfm = only_lisfm || std::string(argv[i]) == "--only_lisfm";
    knn = knn || std::string(argv[i]) == "--knn";
    stages = stages || std::string(argv[i]) == "--stages";
    bayes_no_view_gates = bayes_no_view_gates || std::string(argv[i]) == "--bayes_no_view_gates" ||
                          std::string(argv[i]) == "--bayes_previous";
  }
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
  if (knn) {
    KnnComparison(dir);
    std::printf("\n");
  }
  std::vector<Pair> pairs;
  {
    Pair p;
    p.name = "registration_lidar_pair";
    p.target = dir + "/registration_lidar_pair/251370668.pcd";
    p.source = dir + "/registration_lidar_pair/251371071.pcd";
    p.reference = ReadMatrix(dir + "/registration_lidar_pair/relative.txt");
    p.source_voxel = 0.25;
    p.target_voxel = 0.1;
    pairs.push_back(p);
  }
  {
    Pair p;
    p.name = "bunny bun0->bun4";
    p.source = dir + "/pointclouds_pcl/bun0.pcd";
    p.target = dir + "/pointclouds_pcl/bun4.pcd";
    p.reference << 0.8806, 0.036481, -0.4724, 0.03453, -0.02354, 0.9992, 0.03326, -0.001519, 0.4732,
        -0.01817, 0.8808, 0.04116, 0, 0, 0, 1;
    p.max_distance = 0.05;
    p.kernel_scale = 0.005;
    pairs.push_back(p);
  }
  const std::vector<Mat4> poses = ReadBalmPoses(dir + "/lidar_balm_realworld_subset/alidarPose.csv");
  for (int k = 30; k < 39 && k + 1 < static_cast<int>(poses.size()); ++k) {
    Pair p;
    p.name = "balm full" + std::to_string(k + 1) + "->full" + std::to_string(k);
    p.target = dir + "/lidar_balm_realworld_subset/scans/full" + std::to_string(k) + ".pcd";
    p.source = dir + "/lidar_balm_realworld_subset/scans/full" + std::to_string(k + 1) + ".pcd";
    p.reference = poses[k].inverse() * poses[k + 1];
    p.source_voxel = 0.25;
    p.target_voxel = 0.1;
    pairs.push_back(p);
  }
  if (stages) {
    std::printf("lisfm stages (ms, median): load = both files through ReadPointPositions; "
                "PCL reader = the same two PCDs through ReadPcdWithPclReader, for comparison\n");
    std::printf("| pair | load | (PCL reader) | voxel grids | tree | registration | iterations | "
                "source / target / normals estimated |\n|---|---|---|---|---|---|---|---|\n");
    for (const Pair& p : pairs) OurStages(p, repeats);
    std::printf("\n");
  }
  if (!ab.empty()) {
    const size_t eq = ab.find('=');
    const std::string name = ab.substr(0, eq);
    IcpOptions variant;
    int* field = name == "coarse_min_points" ? &variant.coarse_min_points
                 : name == "coarse_levels"   ? &variant.coarse_levels
                                             : nullptr;
    if (field == nullptr || eq == std::string::npos) {
      std::fprintf(stderr, "--ab: expected coarse_min_points=N or coarse_levels=N, found '%s'\n", ab.c_str());
      return 2;
    }
    const int def = *field;
    *field = std::stoi(ab.substr(eq + 1));
    std::printf("| pair | %s %d: whole / registration (ms) | default %d | speed-up | "
                "rot / trans err (%d) | rot / trans err (%d) |\n|---|---|---|---|---|---|\n",
                name.c_str(), *field, def, *field, def);
    double sum_a = 0, sum_b = 0;
    for (const Pair& p : pairs) {
      std::vector<double> a, ra, b, rb;
      double unused_bayes = 0, unused_closed = 0;
      Outcome oa, ob;
      for (int k = 0; k < repeats; ++k) {
        // Which of the two runs first alternates too (warm caches favour the second).
        for (const bool run_a : {k % 2 == 0, k % 2 != 0}) {
          Outcome& o = run_a ? oa : ob;
          o = RunOurs(p, false, &unused_bayes, &unused_closed, run_a ? variant : IcpOptions());
          (run_a ? a : b).push_back(o.ms);
          (run_a ? ra : rb).push_back(o.reg_ms);
        }
      }
      double rot_a, tr_a, rot_b, tr_b;
      Errors(oa.T, p.reference, &rot_a, &tr_a);
      Errors(ob.T, p.reference, &rot_b, &tr_b);
      std::printf("| %s | %.1f / %.1f | %.1f / %.1f | %.2fx | %.3f deg / %.4f m | %.3f deg / %.4f m |\n",
                  p.name.c_str(), Median(a), Median(ra), Median(b), Median(rb), Median(a) / Median(b),
                  rot_a, tr_a, rot_b, tr_b);
      sum_a += Median(a);
      sum_b += Median(b);
    }
    std::printf("sum of the medians: %.1f / %.1f ms (%.2fx)\n", sum_a, sum_b, sum_a / sum_b);
    return 0;
  }
  std::printf("| pair | method | whole process (ms) | registration alone (ms) | rot err (deg) | trans err (m) |\n|---|---|---|---|---|---|\n");
  for (const Pair& p : pairs) {
    struct Method {
      std::string name;
      std::function<Outcome()> run;
    };
    double bayes_ms = 0, closed_ms = 0;
    std::vector<double> bayes_times, closed_times;
    const std::vector<Method> methods = {
        {"lisfm point-to-plane", [&] {
           auto o = RunOurs(p, false, &bayes_ms, &closed_ms);
           closed_times.push_back(closed_ms);
           return o;
         }},
        {"PCL ICPWithNormals", [&] { return RunPclPointToPlane(p); }},
        {"PCL GICP", [&] { return RunPclGicp(p); }},
        {"Open3D point-to-plane", [&] { return RunOpen3d(p); }},
    };
    // Interleaved: each round runs every method once, so that a slow spell of the
    // shared host hits all methods of a pair alike (the ratios are what we report).
    std::vector<std::vector<double>> times(methods.size()), reg_times(methods.size());
    std::vector<Outcome> last(methods.size());
    for (int r = 0; r < repeats; ++r) {
      for (size_t m = 0; m < methods.size(); ++m) {
        if (only_lisfm && methods[m].name != "lisfm point-to-plane") continue;
        last[m] = methods[m].run();
        times[m].push_back(last[m].ms);
        reg_times[m].push_back(last[m].reg_ms);
      }
    }
    for (size_t m = 0; m < methods.size(); ++m) {
      if (times[m].empty()) continue;
      double rot, trans;
      Errors(last[m].T, p.reference, &rot, &trans);
      std::printf("| %s | %s | %.1f | %.1f | %.3f | %.4f |\n", p.name.c_str(), methods[m].name.c_str(),
                  Median(times[m]), Median(reg_times[m]), rot, trans);
      std::fflush(stdout);
    }
    if (only_lisfm) continue;
    RunOurs(p, true, &bayes_ms, &closed_ms);
    if (bayes_no_view_gates) {
      g_bayes_no_view_gates = true;
      double no_gates_ms = 0, unused = 0;
      RunOurs(p, true, &no_gates_ms, &unused);
      g_bayes_no_view_gates = false;
    }
    std::printf("| %s | lisfm Bayesian ICP (ICP + SGLD) | | %.1f | | |\n| %s | lisfm closed-form covariance (on top of ICP) | | %.3f | | |\n",
                p.name.c_str(), bayes_ms, p.name.c_str(), Median(closed_times));
  }
  return 0;
}
