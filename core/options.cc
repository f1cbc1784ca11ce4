#include "core/options.h"

#include <algorithm>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>

#include <CLI/CLI.hpp>
#include <yaml-cpp/yaml.h>

#include "core/errors.h"
#include "core/file_utils.h"
#include "core/logging.h"

namespace lisfm {

struct OptionManager::Entry {
  std::string name;
  std::string help;
  std::function<std::string()> to_string;
  CLI::Option* option = nullptr;
  bool required = false;
  bool set_by_config = false;
};

namespace {

std::string DoubleToString(double v) {
  std::ostringstream s;
  s << std::setprecision(std::numeric_limits<double>::max_digits10 - 2) << v;
  return s.str();
}

void FlattenYaml(const YAML::Node& node,
                 const std::string& prefix,
                 std::vector<std::pair<std::string, YAML::Node>>* out) {
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    const std::string name = prefix.empty() ? key : prefix + "." + key;
    if (kv.second.IsMap()) {
      FlattenYaml(kv.second, name, out);
    } else {
      out->emplace_back(name, kv.second);
    }
  }
}

}  // namespace

int LevenshteinDistance(const std::string& a, const std::string& b) {
  std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int sub = prev[j - 1] + (std::tolower(a[i - 1]) == std::tolower(b[j - 1]) ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string NearestName(const std::string& name, const std::vector<std::string>& candidates) {
  std::string best;
  int best_d = std::numeric_limits<int>::max();
  for (const auto& c : candidates) {
    int d = LevenshteinDistance(name, c);
    // A name that matches the part after the section ("max_distance" for
    // "Icp.max_distance") is a good suggestion too.
    const auto dot = c.rfind('.');
    if (dot != std::string::npos) d = std::min(d, LevenshteinDistance(name, c.substr(dot + 1)) + 1);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  const int limit = std::max(2, static_cast<int>(name.size()) / 3);
  return best_d <= limit ? best : "";
}

OptionManager::OptionManager(std::string command, std::string description)
    : command_(std::move(command)),
      description_(std::move(description)),
      app_(std::make_unique<CLI::App>(description_, command_)) {
  app_->set_help_flag();  // help is handled by us
  app_->allow_extras(true);
  AddString("config_path", &config_path_,
            "YAML file with option values (same names); the command line overrides it");
  AddBool("verbose", &verbose_, "log debug messages (and solver output)");
  AddBool("quiet", &quiet_, "log warnings and errors only");
}

OptionManager::~OptionManager() = default;

OptionManager::Entry& OptionManager::Register(const std::string& name,
                                              const std::string& help,
                                              std::function<std::string()> to_string,
                                              CLI::Option* option) {
  for (const auto& e : entries_) {
    THROW_CHECK_MSG(e->name != name, "option registered twice: " << name);
  }
  auto entry = std::make_unique<Entry>();
  entry->name = name;
  entry->help = help;
  entry->to_string = std::move(to_string);
  entry->option = option;
  entries_.push_back(std::move(entry));
  return *entries_.back();
}

void OptionManager::AddBool(const std::string& name, bool* value, const std::string& help) {
  // COLMAP style `--name 0|1`; a bare `--name` means 1.
  auto* opt = app_->add_option("--" + name, *value, help)->expected(0, 1)->default_str("1");
  Register(name, help, [value] { return std::string(*value ? "1" : "0"); }, opt);
}

void OptionManager::AddInt(const std::string& name, int* value, const std::string& help) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Register(name, help, [value] { return std::to_string(*value); }, opt);
}

void OptionManager::AddInt64(const std::string& name, int64_t* value, const std::string& help) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Register(name, help, [value] { return std::to_string(*value); }, opt);
}

void OptionManager::AddDouble(const std::string& name, double* value, const std::string& help) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Register(name, help, [value] { return DoubleToString(*value); }, opt);
}

void OptionManager::AddString(const std::string& name,
                              std::string* value,
                              const std::string& help) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Register(name, help, [value] { return *value; }, opt);
}

void OptionManager::AddChoice(const std::string& name,
                              std::string* value,
                              const std::vector<std::string>& choices,
                              const std::string& help) {
  std::string joined;
  for (const auto& c : choices) joined += (joined.empty() ? "" : "|") + c;
  auto* opt = app_->add_option("--" + name, *value, help + " {" + joined + "}");
  opt->check(CLI::IsMember(choices));
  Register(name, help + " {" + joined + "}", [value] { return *value; }, opt);
}

void OptionManager::AddRequiredString(const std::string& name,
                                      std::string* value,
                                      const std::string& help) {
  AddString(name, value, help);
  entries_.back()->required = true;
}

std::vector<std::string> OptionManager::Names() const {
  std::vector<std::string> names;
  for (const auto& e : entries_) names.push_back(e->name);
  return names;
}

bool OptionManager::IsSet(const std::string& name) const {
  for (const auto& e : entries_) {
    if (e->name == name) return e->set_by_config || e->option->count() > 0;
  }
  throw InternalError("IsSet: unknown option " + name);
}

std::string OptionManager::HelpText() const {
  std::ostringstream s;
  s << "Usage: " << command_ << " [options]\n" << description_ << "\n\nOptions:\n";
  s << "  -h [ --help ]\n";
  size_t width = 0;
  for (const auto& e : entries_) width = std::max(width, e->name.size());
  for (const auto& e : entries_) {
    s << "  --" << std::left << std::setw(static_cast<int>(width) + 2) << e->name;
    if (e->required) {
      s << "(required) ";
    } else {
      const std::string def = e->to_string();
      s << "(=" << (def.empty() ? "\"\"" : def) << ") ";
    }
    s << e->help << "\n";
  }
  return s.str();
}

void OptionManager::ApplyConfigFile(const std::string& path) {
  if (!FileExists(path)) throw InputError(path, "", "config file not found");
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw InputError(path, "line " + std::to_string(e.mark.line + 1),
                     "malformed YAML: " + e.msg);
  }
  if (root.IsNull()) return;
  if (!root.IsMap()) throw InputError(path, "", "expected a mapping of option names to values");
  std::vector<std::pair<std::string, YAML::Node>> items;
  FlattenYaml(root, "", &items);
  const auto names = Names();
  for (const auto& [name, node] : items) {
    auto it = std::find_if(entries_.begin(), entries_.end(),
                           [&](const auto& e) { return e->name == name; });
    const std::string where = "line " + std::to_string(node.Mark().line + 1);
    if (it == entries_.end()) {
      const std::string near = NearestName(name, names);
      throw InputError(path, where,
                       "unknown option '" + name + "'" +
                           (near.empty() ? "" : " (did you mean '" + near + "'?)"));
    }
    Entry& e = **it;
    if (e.name == "config_path") continue;
    if (e.option->count() > 0) continue;  // the command line wins
    if (!node.IsScalar()) throw InputError(path, where, "option '" + name + "' needs a scalar value");
    try {
      e.option->add_result(node.Scalar());
      e.option->run_callback();
    } catch (const CLI::Error& err) {
      throw InputError(path, where, "bad value for '" + name + "': " + err.what());
    }
    e.set_by_config = true;
  }
}

bool OptionManager::Parse(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help" || a == "help") {
      std::cout << HelpText();
      return false;
    }
  }
  // CLI11 expects argv[0] to be the program.
  try {
    app_->parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    throw UsageError(command_ + ": " + e.what());
  }
  const auto extras = app_->remaining();
  if (!extras.empty()) {
    const auto names = Names();
    for (const auto& x : extras) {
      if (x.rfind("--", 0) == 0) {
        std::string name = x.substr(2);
        const auto eq = name.find('=');
        if (eq != std::string::npos) name = name.substr(0, eq);
        const std::string near = NearestName(name, names);
        throw UsageError(command_ + ": unknown option '--" + name + "'" +
                         (near.empty() ? "" : " (did you mean '--" + near + "'?)") +
                         "; see '" + command_ + " -h'");
      }
    }
    throw UsageError(command_ + ": unexpected argument '" + extras.front() + "'; see '" +
                     command_ + " -h'");
  }
  if (!config_path_.empty()) ApplyConfigFile(config_path_);
  for (const auto& e : entries_) {
    if (e->required && !IsSet(e->name)) {
      throw UsageError(command_ + ": missing required option '--" + e->name + "'; see '" +
                       command_ + " -h'");
    }
  }
  if (verbose_ && quiet_) throw UsageError(command_ + ": --verbose and --quiet exclude each other");
  if (verbose_) SetLogLevel(LogLevel::kDebug);
  if (quiet_) SetLogLevel(LogLevel::kWarning);
  return true;
}

void OptionManager::WriteConfig(const std::string& path) const {
  YAML::Emitter out;
  out << YAML::BeginMap;
  for (const auto& e : entries_) {
    if (e->name == "config_path") continue;
    out << YAML::Key << e->name << YAML::Value << e->to_string();
  }
  out << YAML::EndMap;
  WriteFileAtomically(path, std::string(out.c_str()) + "\n");
}

}  // namespace lisfm
