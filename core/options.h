// Command-line and YAML option handling in COLMAP's conventions (STYLE.md):
//   lisfm <command> --name value --Section.name value [--config_path file.yaml]
// Options are registered by pointer to a field that holds the default. A YAML
// file given by --config_path uses the same names (nested `Section: {name: v}` or
// flat `Section.name: v`); the command line overrides it. `-h/--help` lists every
// option with its default, its range and its aliases. Unknown names are usage
// errors that suggest the nearest registered name (aliases included).
//
// Names are public API: a renamed option keeps its old name as an alias
// (AddAlias), accepted on the command line and in config files; the effective
// config (WriteConfig) uses the current name. Giving an option under two names
// is a usage error.
//
// Value checks: a numeric option may declare an OptionRange, and AddCheck /
// RequireLess add constraints a range cannot express. Parse() validates every
// value after reading the command line and the config file; a violation is one
// error naming the option as the user spelled it, its value and the requirement:
//   --Icp.max_iterations 0 is out of range: must be >= 1
// (UsageError, exit code 2; InputError naming the file and line when the value
// came from the config file). Doubles must always be finite.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace lisfm {

// The allowed values of a numeric option: an interval (each bound optional,
// inclusive or exclusive) and optionally one special value outside it (e.g.
// -1 = all cores). Default-constructed: any value.
class OptionRange {
 public:
  OptionRange() = default;
  static OptionRange AtLeast(double min);      // >= min
  static OptionRange GreaterThan(double min);  // > min
  static OptionRange AtMost(double max);       // <= max
  static OptionRange LessThan(double max);     // < max
  static OptionRange Between(double min, double max);  // [min, max]
  OptionRange AndAtMost(double max) const;   // adds the upper bound <= max
  OptionRange AndLessThan(double max) const;  // adds the upper bound < max
  OptionRange Or(double special) const;      // also accepts exactly `special`

  bool IsBounded() const { return min_ || max_; }
  bool Contains(double value) const;
  // ">= 1", "> 0", "in (0, 2)", "in [0, 1]", "-1 or >= 1"; "" when unbounded.
  std::string ToString() const;
  // For each bound, the nearest value beyond it (integers: the next integer;
  // doubles: the next representable double; an exclusive bound itself).
  std::vector<double> OutsideValues(bool integer) const;

 private:
  std::optional<double> min_, max_, special_;
  bool min_open_ = false, max_open_ = false;
};

// A registered option as seen by tests and generic code.
struct OptionInfo {
  std::string name;
  std::vector<std::string> aliases;
  OptionRange range;
  bool numeric = false;         // int, int64, uint64 or double
  bool integer = false;         // int, int64 or uint64
  const void* field = nullptr;  // the registered field
};

class OptionManager {
 public:
  // `command` is the name shown in help ("lisfm evaluate"); `description` one line.
  OptionManager(std::string command, std::string description);
  ~OptionManager();

  void AddBool(const std::string& name, bool* value, const std::string& help);
  void AddInt(const std::string& name,
              int* value,
              const std::string& help,
              const OptionRange& range = {});
  void AddInt64(const std::string& name,
                int64_t* value,
                const std::string& help,
                const OptionRange& range = {});
  // Negative values are rejected by the parser (no wrap-around).
  void AddUint64(const std::string& name,
                 uint64_t* value,
                 const std::string& help,
                 const OptionRange& range = {});
  void AddDouble(const std::string& name,
                 double* value,
                 const std::string& help,
                 const OptionRange& range = {});
  void AddString(const std::string& name, std::string* value, const std::string& help);
  // A string restricted to `choices`.
  void AddChoice(const std::string& name,
                 std::string* value,
                 const std::vector<std::string>& choices,
                 const std::string& help);
  // An enum given by the names of `choices` (name, value).
  template <typename Enum>
  void AddEnum(const std::string& name,
               Enum* value,
               const std::vector<std::pair<std::string, Enum>>& choices,
               const std::string& help);
  // Same as AddString, but the option must be given (command line or config file).
  void AddRequiredString(const std::string& name,
                         std::string* value,
                         const std::string& help);

  // `alias` (a former name) also sets the registered option `name`.
  void AddAlias(const std::string& alias, const std::string& name);
  // A constraint on option `name` that a range cannot express: `check` returns
  // "" when the value is fine, else what it must be ("> 0.5 without --trajectory_path").
  void AddCheck(const std::string& name, std::function<std::string()> check);
  // Numeric options: value(smaller) < value(larger). A violation names the
  // option the user gave (`larger` when only it was given, else `smaller`).
  void RequireLess(const std::string& smaller, const std::string& larger);
  // `check` is an options struct's Check() (core/option_check.h). Parse calls
  // it after the value checks above; a failure is reported like a range
  // violation of the registered option bound to the failing field (the
  // requirement text of its CHECK_OPTION_*), so constraints between fields
  // need no second statement here.
  void AddStructCheck(std::function<bool()> check);

  // Adds --verbose (log level debug) and --quiet (warnings only). Called by the
  // constructor; the values are applied to the logging facade by Parse().
  // Parses argv where argv[0] is the command name. Returns false when help was
  // printed (the caller should return 0). Throws UsageError for a bad command
  // line and InputError for a bad config file.
  bool Parse(int argc, char** argv);

  // After Parse: `check_passed` is the result of an options struct's Check().
  // When false, throws the UsageError of LastOptionCheckFailure(), naming the
  // registered option bound to the failing field (its field name otherwise).
  void ThrowUnlessValid(bool check_passed) const;

  // True when the option (name or alias) was given on the command line or in the config file.
  bool IsSet(const std::string& name) const;

  // Sets option `name` (or an alias) from text as the command line would,
  // without the value checks of Parse (programmatic overrides, tests).
  void Set(const std::string& name, const std::string& value);

  std::string HelpText() const;

  // Writes every option with its effective value as flat YAML (`name: value`),
  // loadable again with --config_path.
  void WriteConfig(const std::string& path) const;

  // All registered names (without aliases).
  std::vector<std::string> Names() const;
  // Every registered option with its aliases and range, in registration order.
  std::vector<OptionInfo> Options() const;

 private:
  struct Entry;
  struct Relation {
    std::string smaller, larger;
  };
  Entry& Register(const std::string& name,
                  const std::string& help,
                  std::function<std::string()> to_string,
                  CLI::Option* option,
                  const void* field);
  void AddChoiceFunctions(const std::string& name,
                          const std::vector<std::string>& choices,
                          const std::string& help,
                          std::function<void(const std::string&)> set,
                          std::function<std::string()> get,
                          const void* field);
  Entry* Find(const std::string& name_or_alias) const;
  std::vector<std::string> NamesAndAliases() const;
  std::string SuggestionFor(const std::string& name) const;
  std::vector<std::string> ResolveAliases(int argc, char** argv);
  void ApplyConfigFile(const std::string& path);
  void ValidateValues() const;
  [[noreturn]] void ThrowOutOfRange(const Entry& entry, const std::string& requirement) const;

  std::string command_;
  std::string description_;
  std::unique_ptr<CLI::App> app_;
  std::vector<std::unique_ptr<Entry>> entries_;
  std::vector<Relation> relations_;
  std::vector<std::function<bool()>> struct_checks_;
  std::string config_path_;
  bool verbose_ = false;
  bool quiet_ = false;
};

template <typename Enum>
void OptionManager::AddEnum(const std::string& name,
                            Enum* value,
                            const std::vector<std::pair<std::string, Enum>>& choices,
                            const std::string& help) {
  std::vector<std::string> names;
  for (const auto& c : choices) names.push_back(c.first);
  AddChoiceFunctions(
      name, names, help,
      [value, choices](const std::string& text) {
        for (const auto& c : choices) {
          if (c.first == text) *value = c.second;
        }
      },
      [value, choices]() -> std::string {
        for (const auto& c : choices) {
          if (c.second == *value) return c.first;
        }
        return "";
      },
      value);
}

// Edit distance used to suggest the nearest option or command name.
int LevenshteinDistance(const std::string& a, const std::string& b);
// The candidate nearest to `name`, or "" when none is reasonably close.
std::string NearestName(const std::string& name, const std::vector<std::string>& candidates);

}  // namespace lisfm
