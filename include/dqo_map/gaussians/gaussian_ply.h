#pragma once
// Gaussian export and import in the PLY layout of the original 3DGS code (DESIGN.md "Data on disk"),
// so that common 3DGS viewers open what the map exports and the map can start from what other 3DGS
// tools trained. One vertex per Gaussian, binary little-endian, every property a float except the
// object ID:
//
//   x y z  nx ny nz  f_dc_0 f_dc_1 f_dc_2  opacity  scale_0 scale_1 scale_2  rot_0 rot_1 rot_2 rot_3
//   object_id (uint)
//
// with the 3DGS encodings: normals 0 (unused by 3DGS, kept for the tools that expect them), f_dc the
// degree-0 spherical-harmonic coefficient (colour − 0.5) / C0, opacity as its logit, scale as the
// log of the standard deviations (the map's log-scales as they are), rot the quaternion w x y z (as
// stored: 3DGS does not keep it unit either).
//
// What the layout has no room for is lost on a PLY round trip: types (imported Gaussians are
// opaque, with their opacity kept explicit), confidences, stable flags and birth keyframes. The
// versioned map file (mapping/map_file.h) keeps everything.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/gaussians/gaussian_map.h"

namespace dqo::gs {

// The degree-0 real spherical-harmonic constant, 1 / (2 sqrt(pi)): colour = 0.5 + kShC0 * f_dc.
constexpr double kShC0 = 0.28209479177387814;

// Writes the Gaussians `indices` of `map` (null: all of them, in index order) to `path`. The file is
// written to a temporary sibling and renamed over `path`, so a failure leaves no half-written file
// (and an existing file at `path` unchanged). Returns false with *error naming the file on failure,
// including an index out of range.
bool save_gaussians_ply(const std::string& path, const GaussianMap& map,
                        const std::vector<uint32_t>* indices, std::string* error);

// Reads a 3DGS-layout PLY written by save_gaussians_ply or by other 3DGS tools: binary (little- or
// big-endian) or ascii; properties in any order and of any PLY scalar type; extra properties and
// elements ignored (f_rest_*, normals, faces); object_id optional (0 when absent). Required:
// x y z f_dc_0..2 opacity scale_0..2 rot_0..3 on the element "vertex". Opacity comes back through
// the sigmoid, colour as 0.5 + C0 f_dc (not clamped: a trained 3DGS colour may leave [0, 1]).
// Returns nullopt with *error naming the file when it is not a PLY, lacks a required property or
// is truncated.
std::optional<GaussianMap> load_gaussians_ply(const std::string& path, std::string* error);

}  // namespace dqo::gs
