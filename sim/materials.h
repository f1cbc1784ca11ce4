// Surface materials of the simulated scenes: what a LiDAR return and a camera
// pixel of a surface look like.
//
// Every surface (the `surface_id` of its triangles) has a class, known from
// how the scene builder made it (SurfaceClass: floor, ceiling, wall, object),
// and a material drawn per surface from the class's pool (MaterialPools),
// deterministically from the scene seed. Walls and ceilings draw a
// texture-poor material (plain painted plaster, bare concrete) with probability
// `texture_poor_fraction`, else a textured one (panels, posters, wood).
//
// A material carries
// - LiDAR (905 nm): the diffuse reflectivity rho_d and a specular reflectivity
//   rho_s returned only near normal incidence, so the apparent reflectivity at
//   incidence angle theta is rho(theta) = rho_d m cos(theta) + rho_s cos(theta)^20,
//   m the texture modulation below (sim/lidar_simulator.h uses it for
//   intensity, maximum range and dropouts), and a power-independent dropout
//   probability (transparent glass: the pulse passes through);
// - camera: the mean albedo and the texture contrast c. The rendered albedo of
//   a surface point is albedo + c (a - 0.5), with a in [0.03, 0.97] the
//   procedural texture (sim/texture.h) at the point: c = 1 with albedo 0.5 is
//   the full texture, c ~ 0.05 a plain wall whose gradients are a few DN.
//
// Reflectivities at 905 nm are typical values of the material classes
// (white paint and plaster 0.8, concrete 0.3-0.4, wood 0.5-0.6, black rubber a
// few %, glass 4 % Fresnel reflection at normal incidence, n = 1.5); they are
// model choices, not measurements of the HILTI sites.
//
// Thread safety: the table is immutable; all functions are thread-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lisfm {
namespace sim {

// What the builder made a surface as (see Scene::surface_class).
enum class SurfaceClass : uint8_t {
  kFloor,    // upward-facing slab tops (floors, landings), >= 2 m^2
  kCeiling,  // downward-facing slab bottoms and beams, >= 4 m^2
  kWall,     // vertical faces >= 1.8 m high (walls, pillars)
  kObject,   // everything else: furniture, crates, cars, steps, lintels
};
constexpr int kNumSurfaceClasses = 4;
// "floor", "ceiling", "wall", "object".
const char* SurfaceClassName(SurfaceClass c);

using MaterialId = uint8_t;

struct Material {
  const char* name;
  float reflectivity;      // diffuse reflectivity rho_d at 905 nm, in [0, 1]
  float specularity;       // specular reflectivity rho_s at normal incidence, in [0, 1]
  float dropout;           // probability that a pulse returns nothing regardless of power
  float albedo;            // mean visible albedo, in [0, 1]
  float texture_contrast;  // c: scales the texture's deviation from 0.5
  bool texture_poor;       // a plain surface (few image features)
};

// The material table (index = MaterialId).
const std::vector<Material>& Materials();
// The id of a material name; nullopt for an unknown name.
std::optional<MaterialId> FindMaterial(const std::string& name);
// "painted_plaster, bare_concrete, ..." (for error messages).
std::string MaterialNames();
// The material of surfaces that have none assigned (scenes built from raw
// triangles): textured_panel, the texture and albedo as without materials.
MaterialId DefaultMaterial();

// The rendered albedo at a point whose procedural texture albedo is
// `texture_albedo`: albedo + c (texture_albedo - 0.5), clamped to [0.02, 0.98].
inline float MaterialAlbedo(const Material& m, float texture_albedo) {
  const float a = m.albedo + m.texture_contrast * (texture_albedo - 0.5f);
  return a < 0.02f ? 0.02f : (a > 0.98f ? 0.98f : a);
}

// The materials each surface class draws from (names resolved to ids). A
// wall or ceiling draws from the texture-poor members with probability
// texture_poor_fraction, else from the others (from all members when one kind
// is missing); floors and objects draw from all members.
struct MaterialPools {
  std::vector<MaterialId> pool[kNumSurfaceClasses];
  MaterialPools();  // the defaults below
};
// Defaults: floor {concrete_floor}; ceiling {bare_concrete, painted_plaster,
// textured_panel}; wall {painted_plaster, bare_concrete, textured_panel, wood};
// object {wood, metal, black_rubber, textured_panel, glass}.

struct MaterialOptions {
  // Fraction of wall and ceiling surfaces that are texture-poor (plain paint,
  // bare concrete).
  double texture_poor_fraction = 0.6;
  bool Check() const;
};

// One material per surface: surface s draws from pools.pool[classes[s]] with
// a hash of (seed, s), so the draw of a surface does not depend on the others.
std::vector<MaterialId> AssignMaterials(const std::vector<SurfaceClass>& classes,
                                        const MaterialPools& pools,
                                        double texture_poor_fraction,
                                        uint32_t seed);

}  // namespace sim
}  // namespace lisfm
