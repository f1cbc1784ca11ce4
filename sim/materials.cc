#include "sim/materials.h"

#include "core/errors.h"
#include "core/option_check.h"
#include "sim/hash_random.h"

namespace lisfm {
namespace sim {
namespace {

// name, rho_d, rho_s, dropout, albedo, texture contrast, texture-poor.
const std::vector<Material> kMaterials = {
    {"painted_plaster", 0.80f, 0.00f, 0.0f, 0.75f, 0.04f, true},
    {"bare_concrete", 0.35f, 0.00f, 0.0f, 0.45f, 0.10f, true},
    {"concrete_floor", 0.30f, 0.02f, 0.0f, 0.40f, 0.35f, false},
    {"textured_panel", 0.50f, 0.00f, 0.0f, 0.50f, 1.00f, false},
    {"wood", 0.55f, 0.00f, 0.0f, 0.50f, 0.70f, false},
    {"metal", 0.05f, 0.60f, 0.0f, 0.55f, 0.30f, false},
    {"glass", 0.01f, 0.04f, 0.5f, 0.25f, 0.15f, false},
    {"black_rubber", 0.03f, 0.00f, 0.0f, 0.06f, 0.30f, false},
    {"cloth", 0.45f, 0.00f, 0.0f, 0.35f, 0.50f, false},
};

MaterialId Id(const char* name) { return *FindMaterial(name); }

}  // namespace

const char* SurfaceClassName(SurfaceClass c) {
  switch (c) {
    case SurfaceClass::kFloor:
      return "floor";
    case SurfaceClass::kCeiling:
      return "ceiling";
    case SurfaceClass::kWall:
      return "wall";
    case SurfaceClass::kObject:
      return "object";
  }
  return "object";
}

const std::vector<Material>& Materials() { return kMaterials; }

std::optional<MaterialId> FindMaterial(const std::string& name) {
  for (size_t i = 0; i < kMaterials.size(); ++i) {
    if (name == kMaterials[i].name) return static_cast<MaterialId>(i);
  }
  return std::nullopt;
}

std::string MaterialNames() {
  std::string names;
  for (const Material& m : kMaterials) names += (names.empty() ? "" : ", ") + std::string(m.name);
  return names;
}

MaterialId DefaultMaterial() {
  static const MaterialId id = Id("textured_panel");
  return id;
}

MaterialPools::MaterialPools() {
  pool[static_cast<int>(SurfaceClass::kFloor)] = {Id("concrete_floor")};
  pool[static_cast<int>(SurfaceClass::kCeiling)] = {
      Id("bare_concrete"), Id("painted_plaster"), Id("textured_panel")};
  pool[static_cast<int>(SurfaceClass::kWall)] = {
      Id("painted_plaster"), Id("bare_concrete"), Id("textured_panel"), Id("wood")};
  pool[static_cast<int>(SurfaceClass::kObject)] = {
      Id("wood"), Id("metal"), Id("black_rubber"), Id("textured_panel"), Id("glass")};
}

bool MaterialOptions::Check() const {
  CHECK_OPTION_MSG(texture_poor_fraction,
                   texture_poor_fraction >= 0 && texture_poor_fraction <= 1,
                   "in [0, 1]");
  return true;
}

std::vector<MaterialId> AssignMaterials(const std::vector<SurfaceClass>& classes,
                                        const MaterialPools& pools,
                                        double texture_poor_fraction,
                                        uint32_t seed) {
  for (const auto& pool : pools.pool) THROW_CHECK(!pool.empty());
  std::vector<MaterialId> out(classes.size());
  const uint64_t key = Mix64(static_cast<uint64_t>(seed) * 0x9E3779B97F4A7C15ULL + 0x4d415453ULL);
  for (size_t s = 0; s < classes.size(); ++s) {
    const uint64_t h = Mix64(key + s);
    const double u_kind = static_cast<double>(h >> 40) * (1.0 / 16777216.0);  // 24 bits
    const uint32_t pick = static_cast<uint32_t>(h & 0xffffffu);
    const SurfaceClass c = classes[s];
    const std::vector<MaterialId>& pool = pools.pool[static_cast<int>(c)];
    std::vector<MaterialId> candidates;
    if (c == SurfaceClass::kWall || c == SurfaceClass::kCeiling) {
      const bool want_poor = u_kind < texture_poor_fraction;
      for (MaterialId m : pool) {
        if (Materials()[m].texture_poor == want_poor) candidates.push_back(m);
      }
    }
    if (candidates.empty()) candidates = pool;
    out[s] = candidates[pick % candidates.size()];
  }
  return out;
}

}  // namespace sim
}  // namespace lisfm
