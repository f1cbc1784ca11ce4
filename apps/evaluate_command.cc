// `lisfm evaluate`: filled in by the evaluation work.
#include "apps/commands.h"
#include "core/options.h"

namespace lisfm {
int RunEvaluate(int argc, char** argv) {
  OptionManager options("lisfm evaluate", "score a trajectory against ground truth");
  std::string reference;
  options.AddRequiredString("reference", &reference, "reference trajectory");
  if (!options.Parse(argc, argv)) return 0;
  return 0;
}
}  // namespace lisfm
