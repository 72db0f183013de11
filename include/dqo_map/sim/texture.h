#pragma once
// Procedural solid textures: a colour as a function of the 3D point in the surface's own frame, so
// no UVs are needed and a texture moves with its object. Enough structure (checker corners, noise
// blobs, stripes, wood rings) for ORB features and for colour losses to have something to bite on.

#include <Eigen/Core>
#include <cstdint>
#include <string>

namespace dqo::sim {

enum class TextureType {
  kUniform,  // colour_a everywhere
  kChecker,  // squares of side `scale`, on the two axes across the surface
  kNoise,    // fractal value noise between colour_a and colour_b, feature size `scale`
  kStripes,  // bands of width `scale` / 2 along `axis`, edges softened by `softness`
  kWood,     // rings of spacing `scale` around the local z axis, disturbed by noise
};

struct Texture {
  TextureType type = TextureType::kUniform;
  Eigen::Vector3f colour_a = Eigen::Vector3f::Constant(0.7f);  // linear RGB in [0, 1]
  Eigen::Vector3f colour_b = Eigen::Vector3f::Constant(0.3f);
  double scale = 0.1;     // metres: checker square, noise feature, stripe period, ring spacing
  int octaves = 3;        // noise and wood
  double contrast = 1.0;  // noise: gain around the mid value before clamping
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // stripes: direction across the bands
  double softness = 0.1;  // stripes: fraction of a period over which the colours blend
  uint32_t seed = 0;      // noise and wood lattice
};

// Colour at local point p of a surface with local normal n (n picks the checker's axes).
// `footprint` is the size of the pixel on the surface, in the same units as p: detail finer than it
// is averaged away (filtered checker and stripe edges, noise octaves faded), so a far checker
// floor turns grey instead of flickering into moiré that no real camera would see.
Eigen::Vector3f evaluate_texture(const Texture& texture, const Eigen::Vector3d& p,
                                 const Eigen::Vector3d& n, double footprint = 0.0);

// Fractal value noise in [0, 1] (sum of `octaves` octaves, each half the size and weight).
float value_noise(const Eigen::Vector3d& p, int octaves, uint32_t seed);

// "checker", "noise", ...; false for an unknown name.
bool texture_type_from_string(const std::string& name, TextureType* type);

}  // namespace dqo::sim
