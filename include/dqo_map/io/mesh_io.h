#pragma once
// Triangle mesh files through Open3D (which stays inside io/'s mesh_io.cpp).
//
// load_mesh has the signature of sim/'s mesh loader hook,
//   std::optional<TriangleMesh>(const std::string& path, std::string* error),
// so the scene loader can take `&dqo::load_mesh` without sim/ depending on io/.

#include <optional>
#include <string>

#include "dqo_map/common/triangle_mesh.h"

namespace dqo {

// Reads a PLY or OBJ file (STL and OFF work too: whatever Open3D reads). Fails, with an error
// naming the file, when the file is missing, does not parse, has no triangles, or has a triangle
// index outside the vertex list or a non-finite vertex. Vertex colours are kept when the file has
// them (an OBJ file without colours yields none).
std::optional<TriangleMesh> load_mesh(const std::string& path, std::string* error = nullptr);

// Binary little-endian PLY: vertices as doubles (exact round trip), faces, vertex colours as 8-bit
// when the mesh has them. Written to a temporary sibling and renamed, so no half-written file is
// left on failure.
bool save_mesh_ply(const std::string& path, const TriangleMesh& mesh,
                   std::string* error = nullptr);

}  // namespace dqo
