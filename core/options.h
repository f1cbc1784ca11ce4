// Command-line and YAML option handling in COLMAP's conventions (STYLE.md):
//   lisfm <command> --name value --Section.name value [--config_path file.yaml]
// Options are registered by pointer to a field that holds the default. A YAML
// file given by --config_path uses the same names (nested `Section: {name: v}` or
// flat `Section.name: v`); the command line overrides it. `-h/--help` lists every
// option with its default. Unknown names are usage errors that suggest the
// nearest registered name.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace lisfm {

class OptionManager {
 public:
  // `command` is the name shown in help ("lisfm evaluate"); `description` one line.
  OptionManager(std::string command, std::string description);
  ~OptionManager();

  void AddBool(const std::string& name, bool* value, const std::string& help);
  void AddInt(const std::string& name, int* value, const std::string& help);
  void AddInt64(const std::string& name, int64_t* value, const std::string& help);
  void AddDouble(const std::string& name, double* value, const std::string& help);
  void AddString(const std::string& name, std::string* value, const std::string& help);
  // A string restricted to `choices`.
  void AddChoice(const std::string& name,
                 std::string* value,
                 const std::vector<std::string>& choices,
                 const std::string& help);
  // Same as AddString, but the option must be given (command line or config file).
  void AddRequiredString(const std::string& name,
                         std::string* value,
                         const std::string& help);

  // Adds --verbose (log level debug) and --quiet (warnings only). Called by the
  // constructor; the values are applied to the logging facade by Parse().
  // Parses argv where argv[0] is the command name. Returns false when help was
  // printed (the caller should return 0). Throws UsageError for a bad command
  // line and InputError for a bad config file.
  bool Parse(int argc, char** argv);

  // True when the option was given on the command line or in the config file.
  bool IsSet(const std::string& name) const;

  std::string HelpText() const;

  // Writes every option with its effective value as flat YAML (`name: value`),
  // loadable again with --config_path.
  void WriteConfig(const std::string& path) const;

  // All registered names (for suggestions and tests).
  std::vector<std::string> Names() const;

 private:
  struct Entry;
  Entry& Register(const std::string& name,
                  const std::string& help,
                  std::function<std::string()> to_string,
                  CLI::Option* option);
  void ApplyConfigFile(const std::string& path);

  std::string command_;
  std::string description_;
  std::unique_ptr<CLI::App> app_;
  std::vector<std::unique_ptr<Entry>> entries_;
  std::string config_path_;
  bool verbose_ = false;
  bool quiet_ = false;
};

// Edit distance used to suggest the nearest option or command name.
int LevenshteinDistance(const std::string& a, const std::string& b);
// The candidate nearest to `name`, or "" when none is reasonably close.
std::string NearestName(const std::string& name, const std::vector<std::string>& candidates);

}  // namespace lisfm
