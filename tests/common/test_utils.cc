#include "tests/common/test_utils.h"

#include <cxxabi.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <typeinfo>

#include "core/errors.h"

namespace lisfm {
namespace test {

namespace fs = std::filesystem;

TempDir::TempDir() {
  std::string tmpl = (fs::temp_directory_path() / "lisfm_test_XXXXXX").string();
  if (mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::string SharedDataDir() {
  const char* env = std::getenv("LISFM_TEST_DATA_DIR");
  std::string dir = env ? env : "";
  if (dir.empty() || !fs::is_directory(dir)) return "";
  return dir;
}

std::string SharedData(const std::string& relative) {
  const std::string dir = SharedDataDir();
  if (dir.empty()) return "";
  const std::string p = dir + "/" + relative;
  return fs::exists(p) ? p : "";
}

std::string SourceDir() {
  const char* env = std::getenv("LISFM_SOURCE_DIR");
  return env ? env : ".";
}

std::string LisfmBinary() {
  const char* env = std::getenv("LISFM_BINARY");
  return env ? env : "lisfm";
}

void WriteText(const std::string& path, const std::string& contents) {
  std::ofstream out(path, std::ios::binary);
  out << contents;
}

int RunCommand(const std::string& command, std::string* output) {
  output->clear();
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) output->append(buf.data(), n);
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

Eigen::MatrixXd NumericJacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                const Eigen::VectorXd& x,
                                double step) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd J(f0.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd xp = x, xm = x;
    xp(i) += step;
    xm(i) -= step;
    J.col(i) = (f(xp) - f(xm)) / (2 * step);
  }
  return J;
}

std::mt19937& Rng() {
  static std::mt19937 rng(kTestSeed);
  return rng;
}

SE3 RandomPose(double max_angle_rad, double max_translation) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vec3 axis(u(Rng()), u(Rng()), u(Rng()));
  axis.normalize();
  const double angle = max_angle_rad * 0.5 * (u(Rng()) + 1.0);
  Vec3 t(u(Rng()), u(Rng()), u(Rng()));
  return SE3(so3::Exp(angle * axis), max_translation * t);
}

::testing::AssertionResult PosesNear(const SE3& a,
                                     const SE3& b,
                                     double max_angle_rad,
                                     double max_translation) {
  const double angle = so3::AngularDistance(a.rotation(), b.rotation());
  const double dt = (a.translation() - b.translation()).norm();
  if (angle <= max_angle_rad && dt <= max_translation) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "poses differ by " << angle << " rad (max " << max_angle_rad << ") and " << dt
         << " m (max " << max_translation << ")\n  a: q=" << a.rotation().coeffs().transpose()
         << " t=" << a.translation().transpose() << "\n  b: q=" << b.rotation().coeffs().transpose()
         << " t=" << b.translation().transpose();
}

::testing::AssertionResult ThrowsInputError(const std::function<void()>& f,
                                            const std::vector<std::string>& fragments) {
  try {
    f();
  } catch (const InputError& e) {
    const std::string message = e.what();
    std::string missing;
    for (const std::string& fragment : fragments) {
      if (message.find(fragment) == std::string::npos) missing += " \"" + fragment + "\"";
    }
    if (missing.empty()) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure()
           << "the InputError message lacks" << missing << "\n  message: " << message;
  } catch (const std::exception& e) {
    int status = 0;
    char* name = abi::__cxa_demangle(typeid(e).name(), nullptr, nullptr, &status);
    const std::string type = status == 0 && name != nullptr ? name : typeid(e).name();
    std::free(name);
    return ::testing::AssertionFailure()
           << "expected lisfm::InputError, got " << type << ": " << e.what();
  } catch (...) {
    return ::testing::AssertionFailure()
           << "expected lisfm::InputError, got an exception not derived from "
              "std::exception";
  }
  return ::testing::AssertionFailure() << "expected lisfm::InputError, nothing was thrown";
}

}  // namespace test
}  // namespace lisfm
