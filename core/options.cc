#include "core/options.h"

#include <algorithm>
#include <cmath>
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
#include "core/option_check.h"

namespace lisfm {

struct OptionManager::Entry {
  std::string name;
  std::vector<std::string> aliases;
  std::string help;
  std::function<std::string()> to_string;
  std::function<double()> number;  // numeric options only
  bool integer = false;
  bool is_double = false;
  const void* field = nullptr;
  OptionRange range;
  std::vector<std::function<std::string()>> checks;
  CLI::Option* option = nullptr;
  bool required = false;
  bool on_command_line = false;
  bool set_by_config = false;
  int config_line = 0;   // 1-based line of the value in the config file
  std::string given_as;  // the name used on the command line (the name or an alias)
};

namespace {

std::string DoubleToString(double v) {
  std::ostringstream s;
  s << std::setprecision(std::numeric_limits<double>::max_digits10 - 2) << v;
  return s.str();
}

// Flattens nested maps into dotted option names; a key that is not a plain scalar
// (a map or list used as a key, valid YAML) is an InputError naming `path` and the line.
void FlattenYaml(const std::string& path,
                 const YAML::Node& node,
                 const std::string& prefix,
                 std::vector<std::pair<std::string, YAML::Node>>* out) {
  for (const auto& kv : node) {
    if (!kv.first.IsScalar()) {
      throw InputError(path, "line " + std::to_string(kv.first.Mark().line + 1),
                       "expected an option name as map key, found a " +
                           std::string(kv.first.IsMap() ? "map" : "list"));
    }
    const std::string key = kv.first.Scalar();
    const std::string name = prefix.empty() ? key : prefix + "." + key;
    if (kv.second.IsMap()) {
      FlattenYaml(path, kv.second, name, out);
    } else {
      out->emplace_back(name, kv.second);
    }
  }
}

}  // namespace

OptionRange OptionRange::AtLeast(double min) {
  OptionRange r;
  r.min_ = min;
  return r;
}

OptionRange OptionRange::GreaterThan(double min) {
  OptionRange r;
  r.min_ = min;
  r.min_open_ = true;
  return r;
}

OptionRange OptionRange::AtMost(double max) { return OptionRange().AndAtMost(max); }

OptionRange OptionRange::LessThan(double max) { return OptionRange().AndLessThan(max); }

OptionRange OptionRange::Between(double min, double max) { return AtLeast(min).AndAtMost(max); }

OptionRange OptionRange::AndAtMost(double max) const {
  OptionRange r = *this;
  r.max_ = max;
  r.max_open_ = false;
  return r;
}

OptionRange OptionRange::AndLessThan(double max) const {
  OptionRange r = *this;
  r.max_ = max;
  r.max_open_ = true;
  return r;
}

OptionRange OptionRange::Or(double special) const {
  OptionRange r = *this;
  r.special_ = special;
  return r;
}

bool OptionRange::Contains(double value) const {
  if (special_ && value == *special_) return true;
  if (min_ && !(min_open_ ? value > *min_ : value >= *min_)) return false;
  if (max_ && !(max_open_ ? value < *max_ : value <= *max_)) return false;
  return true;
}

std::string OptionRange::ToString() const {
  std::string s;
  if (min_ && max_) {
    s = std::string("in ") + (min_open_ ? "(" : "[") + DoubleToString(*min_) + ", " +
        DoubleToString(*max_) + (max_open_ ? ")" : "]");
  } else if (min_) {
    s = (min_open_ ? "> " : ">= ") + DoubleToString(*min_);
  } else if (max_) {
    s = (max_open_ ? "< " : "<= ") + DoubleToString(*max_);
  } else {
    return "";
  }
  return special_ ? DoubleToString(*special_) + " or " + s : s;
}

std::vector<double> OptionRange::OutsideValues(bool integer) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> values;
  if (min_) {
    values.push_back(min_open_ ? *min_ : integer ? *min_ - 1 : std::nextafter(*min_, -kInf));
  }
  if (max_) {
    values.push_back(max_open_ ? *max_ : integer ? *max_ + 1 : std::nextafter(*max_, kInf));
  }
  std::vector<double> outside;
  for (const double v : values) {
    if (!Contains(v)) outside.push_back(v);
  }
  return outside;
}

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
                                              CLI::Option* option,
                                              const void* field) {
  THROW_CHECK_MSG(Find(name) == nullptr, "option registered twice: " << name);
  auto entry = std::make_unique<Entry>();
  entry->name = name;
  entry->help = help;
  entry->to_string = std::move(to_string);
  entry->option = option;
  entry->field = field;
  entries_.push_back(std::move(entry));
  return *entries_.back();
}

void OptionManager::AddBool(const std::string& name, bool* value, const std::string& help) {
  // COLMAP style `--name 0|1`; a bare `--name` means 1.
  auto* opt = app_->add_option("--" + name, *value, help)->expected(0, 1)->default_str("1");
  Register(name, help, [value] { return std::string(*value ? "1" : "0"); }, opt, value);
}

void OptionManager::AddInt(const std::string& name,
                           int* value,
                           const std::string& help,
                           const OptionRange& range) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Entry& e = Register(name, help, [value] { return std::to_string(*value); }, opt, value);
  e.number = [value] { return static_cast<double>(*value); };
  e.integer = true;
  e.range = range;
}

void OptionManager::AddInt64(const std::string& name,
                             int64_t* value,
                             const std::string& help,
                             const OptionRange& range) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Entry& e = Register(name, help, [value] { return std::to_string(*value); }, opt, value);
  e.number = [value] { return static_cast<double>(*value); };
  e.integer = true;
  e.range = range;
}

void OptionManager::AddUint64(const std::string& name,
                              uint64_t* value,
                              const std::string& help,
                              const OptionRange& range) {
  // CLI11 would wrap "-1" around to 2^64 - 1.
  auto* opt = app_->add_option("--" + name, *value, help)->check(CLI::NonNegativeNumber);
  Entry& e = Register(name, help, [value] { return std::to_string(*value); }, opt, value);
  e.number = [value] { return static_cast<double>(*value); };
  e.integer = true;
  e.range = range;
}

void OptionManager::AddDouble(const std::string& name,
                              double* value,
                              const std::string& help,
                              const OptionRange& range) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Entry& e = Register(name, help, [value] { return DoubleToString(*value); }, opt, value);
  e.number = [value] { return *value; };
  e.is_double = true;
  e.range = range;
}

void OptionManager::AddString(const std::string& name,
                              std::string* value,
                              const std::string& help) {
  auto* opt = app_->add_option("--" + name, *value, help);
  Register(name, help, [value] { return *value; }, opt, value);
}

void OptionManager::AddChoice(const std::string& name,
                              std::string* value,
                              const std::vector<std::string>& choices,
                              const std::string& help) {
  std::string joined;
  for (const auto& c : choices) joined += (joined.empty() ? "" : "|") + c;
  auto* opt = app_->add_option("--" + name, *value, help + " {" + joined + "}");
  opt->check(CLI::IsMember(choices));
  Register(name, help + " {" + joined + "}", [value] { return *value; }, opt, value);
}

void OptionManager::AddChoiceFunctions(const std::string& name,
                                       const std::vector<std::string>& choices,
                                       const std::string& help,
                                       std::function<void(const std::string&)> set,
                                       std::function<std::string()> get,
                                       const void* field) {
  std::string joined;
  for (const auto& c : choices) joined += (joined.empty() ? "" : "|") + c;
  auto* opt = app_->add_option_function<std::string>("--" + name, std::move(set),
                                                     help + " {" + joined + "}");
  opt->check(CLI::IsMember(choices));
  Register(name, help + " {" + joined + "}", std::move(get), opt, field);
}

void OptionManager::AddRequiredString(const std::string& name,
                                      std::string* value,
                                      const std::string& help) {
  AddString(name, value, help);
  entries_.back()->required = true;
}

void OptionManager::AddAlias(const std::string& alias, const std::string& name) {
  THROW_CHECK_MSG(Find(alias) == nullptr, "option alias registered twice: " << alias);
  Entry* e = Find(name);
  THROW_CHECK_MSG(e != nullptr, "alias " << alias << " of an unknown option " << name);
  e->aliases.push_back(alias);
}

void OptionManager::AddCheck(const std::string& name, std::function<std::string()> check) {
  Entry* e = Find(name);
  THROW_CHECK_MSG(e != nullptr, "AddCheck: unknown option " << name);
  e->checks.push_back(std::move(check));
}

void OptionManager::RequireLess(const std::string& smaller, const std::string& larger) {
  const Entry* a = Find(smaller);
  const Entry* b = Find(larger);
  THROW_CHECK_MSG(a != nullptr && a->number, "RequireLess: not a numeric option: " << smaller);
  THROW_CHECK_MSG(b != nullptr && b->number, "RequireLess: not a numeric option: " << larger);
  relations_.push_back({a->name, b->name});
}

void OptionManager::AddStructCheck(std::function<bool()> check) {
  struct_checks_.push_back(std::move(check));
}

OptionManager::Entry* OptionManager::Find(const std::string& name_or_alias) const {
  for (const auto& e : entries_) {
    if (e->name == name_or_alias) return e.get();
    for (const auto& a : e->aliases) {
      if (a == name_or_alias) return e.get();
    }
  }
  return nullptr;
}

std::vector<std::string> OptionManager::Names() const {
  std::vector<std::string> names;
  for (const auto& e : entries_) names.push_back(e->name);
  return names;
}

std::vector<std::string> OptionManager::NamesAndAliases() const {
  std::vector<std::string> names;
  for (const auto& e : entries_) {
    names.push_back(e->name);
    names.insert(names.end(), e->aliases.begin(), e->aliases.end());
  }
  return names;
}

std::vector<OptionInfo> OptionManager::Options() const {
  std::vector<OptionInfo> infos;
  for (const auto& e : entries_) {
    OptionInfo info;
    info.name = e->name;
    info.aliases = e->aliases;
    info.range = e->range;
    info.numeric = static_cast<bool>(e->number);
    info.integer = e->integer;
    info.field = e->field;
    infos.push_back(info);
  }
  return infos;
}

std::string OptionManager::SuggestionFor(const std::string& name) const {
  const std::string near = NearestName(name, NamesAndAliases());
  if (near.empty()) return "";
  return Find(near)->name;  // an alias suggests the current name
}

bool OptionManager::IsSet(const std::string& name) const {
  const Entry* e = Find(name);
  if (e == nullptr) throw InternalError("IsSet: unknown option " + name);
  return e->set_by_config || e->on_command_line;
}

void OptionManager::Set(const std::string& name, const std::string& value) {
  Entry* e = Find(name);
  THROW_CHECK_MSG(e != nullptr, "Set: unknown option " << name);
  e->option->clear();
  e->option->add_result(value);
  e->on_command_line = true;
  e->set_by_config = false;
  e->given_as = name;
  try {
    e->option->run_callback();
  } catch (const CLI::Error& err) {
    throw UsageError(command_ + ": bad value for '--" + name + "': " + err.what());
  }
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
      const std::string range = e->range.ToString();
      s << "(=" << (def.empty() ? "\"\"" : def) << (range.empty() ? "" : ", " + range) << ") ";
    }
    s << e->help;
    for (const auto& a : e->aliases) s << " [alias: --" << a << "]";
    s << "\n";
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
  if (root.IsNull()) {
    // An empty file (or one holding only comments) sets no option: legitimate, but
    // most likely not what was meant.
    LogWarning("{}: the config file sets no option", path);
    return;
  }
  if (!root.IsMap()) throw InputError(path, "", "expected a mapping of option names to values");
  std::vector<std::pair<std::string, YAML::Node>> items;
  FlattenYaml(path, root, "", &items);
  std::vector<std::pair<const Entry*, std::string>> seen;  // entry, name used in the file
  for (const auto& [name, node] : items) {
    Entry* found = Find(name);
    const int line = node.Mark().line + 1;
    const std::string where = "line " + std::to_string(line);
    if (found == nullptr) {
      const std::string near = SuggestionFor(name);
      throw InputError(path, where,
                       "unknown option '" + name + "'" +
                           (near.empty() ? "" : " (did you mean '" + near + "'?)"));
    }
    Entry& e = *found;
    for (const auto& [other, other_name] : seen) {
      if (other == &e) {
        throw InputError(path, where,
                         "option '" + e.name + "' given twice (as '" + other_name + "' and '" +
                             name + "'); give it once");
      }
    }
    seen.emplace_back(&e, name);
    if (e.name == "config_path") continue;
    if (e.on_command_line) continue;  // the command line wins
    if (!node.IsScalar()) throw InputError(path, where, "option '" + name + "' needs a scalar value");
    try {
      e.option->add_result(node.Scalar());
      e.option->run_callback();
    } catch (const CLI::Error& err) {
      throw InputError(path, where, "bad value for '" + name + "': " + err.what());
    }
    e.set_by_config = true;
    e.config_line = line;
  }
}

std::vector<std::string> OptionManager::ResolveAliases(int argc, char** argv) {
  std::vector<std::string> args(argv, argv + argc);
  std::vector<std::pair<const Entry*, std::string>> seen;  // entry, name used
  for (size_t i = 1; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg.rfind("--", 0) != 0) continue;
    const size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    Entry* e = Find(name);
    if (e == nullptr) continue;
    for (const auto& [other, other_name] : seen) {
      if (other == e && other_name != name) {
        throw UsageError("--" + other_name + " and --" + name + " are the same option (--" +
                         e->name + "); give it once");
      }
    }
    seen.emplace_back(e, name);
    e->given_as = name;
    if (name != e->name) {
      args[i] = "--" + e->name + (eq == std::string::npos ? "" : arg.substr(eq));
    }
  }
  return args;
}

void OptionManager::ThrowOutOfRange(const Entry& e, const std::string& requirement) const {
  const std::string message =
      " " + e.to_string() + " is out of range: must be " + requirement;
  if (e.set_by_config) {
    throw InputError(config_path_, "line " + std::to_string(e.config_line), e.name + message);
  }
  throw UsageError("--" + (e.given_as.empty() ? e.name : e.given_as) + message);
}

void OptionManager::ValidateValues() const {
  for (const auto& e : entries_) {
    std::string requirement;
    if (e->number) {
      const double v = e->number();
      if (e->is_double && !std::isfinite(v)) {
        requirement = "a finite number";
        if (e->range.IsBounded()) requirement += " " + e->range.ToString();
      } else if (!e->range.Contains(v)) {
        requirement = e->range.ToString();
      }
    }
    for (size_t k = 0; k < e->checks.size() && requirement.empty(); ++k) {
      requirement = e->checks[k]();
    }
    if (!requirement.empty()) ThrowOutOfRange(*e, requirement);
  }
  for (const Relation& r : relations_) {
    const Entry& a = *Find(r.smaller);
    const Entry& b = *Find(r.larger);
    if (a.number() < b.number()) continue;
    if (IsSet(b.name) && !IsSet(a.name)) {
      ThrowOutOfRange(b, "> --" + a.name + " (" + a.to_string() + ")");
    }
    ThrowOutOfRange(a, "< --" + b.name + " (" + b.to_string() + ")");
  }
  for (const auto& check : struct_checks_) ThrowUnlessValid(check());
}

void OptionManager::ThrowUnlessValid(bool check_passed) const {
  if (check_passed) return;
  const OptionCheckFailure& f = LastOptionCheckFailure();
  for (const auto& e : entries_) {
    if (f.field != nullptr && e->field == f.field) ThrowOutOfRange(*e, f.requirement);
  }
  throw UsageError(command_ + ": invalid option value: " + f.ToString());
}

bool OptionManager::Parse(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help" || a == "help") {
      std::cout << HelpText();
      return false;
    }
  }
  std::vector<std::string> args = ResolveAliases(argc, argv);
  std::vector<char*> arg_ptrs;
  for (auto& a : args) arg_ptrs.push_back(a.data());
  // CLI11 expects argv[0] to be the program.
  try {
    app_->parse(static_cast<int>(arg_ptrs.size()), arg_ptrs.data());
  } catch (const CLI::ParseError& e) {
    throw UsageError(command_ + ": " + e.what());
  }
  for (const auto& e : entries_) e->on_command_line = e->option->count() > 0;
  const auto extras = app_->remaining();
  if (!extras.empty()) {
    for (const auto& x : extras) {
      if (x.rfind("--", 0) == 0) {
        std::string name = x.substr(2);
        const auto eq = name.find('=');
        if (eq != std::string::npos) name = name.substr(0, eq);
        const std::string near = SuggestionFor(name);
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
  ValidateValues();
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
