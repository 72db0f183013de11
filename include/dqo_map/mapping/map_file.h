#pragma once
// The versioned map file (DESIGN.md "mapping/"): everything the mapping stage needs to resume, in
// one binary file: every Gaussian attribute, the objects, the keyframe poses, the next object ID
// and a hash of the parameters the map was built with. Numbers are stored in their own width (floats
// as floats, doubles as doubles), so a round trip is exact. Little-endian, no padding:
//
//   offset  bytes  field
//        0      8  magic 89 'D' 'Q' 'O' 'M' 'A' 'P' 0A
//        8      4  u32 version (kMapFileVersion)
//       12      4  u32 header bytes (80)
//       16      8  u64 params_hash
//       24      8  u64 next_object_id
//       32     16  u64 Gaussian count G, u64 Gaussian section bytes (70 G)
//       48     16  u64 object count O, u64 object section bytes
//       64     16  u64 keyframe count K, u64 keyframe section bytes (112 K)
//       80         Gaussian section: the map's arrays one after another, each G entries long:
//                    positions f32x3, log-scales f32x3, rotations f32x4 (w x y z), opacities f32,
//                    colours f32x3, confidences f32, object IDs u32, birth keyframes u32,
//                    types u8, stable flags u8
//                  object section, O records: id u64, class_id i32, observations i32,
//                    confidence f64, quadric centre f64x3, rotation f64x9 (row-major), semi-axes
//                    f64x3, box centre f64x3, rotation f64x9 (row-major), half extents f64x3,
//                    class name (u32 length, bytes)
//                  keyframe section, K records: id u64, stamp f64, fx fy cx cy f64, width height
//                    i32, T_wc quaternion w x y z f64, translation f64x3
//    end-8      8  u64 FNV-1a 64 of every byte before it
//
// Saving writes `path + ".tmp-<pid>"`, flushes it to the disk and renames it over `path`, so a
// crash leaves the old file or the new one, never half of one. Loading checks the magic, the
// version, the sizes against the file's (before allocating anything) and the checksum, and returns
// nothing on any failure: callers keep the map they have.
//
// Keyframe quaternions: SE3 renormalises its quaternion on construction, which moves about a third
// of unit quaternions by an ulp. The file therefore stores, for each pose, a quaternion within a
// few ulps of the pose's that SE3 keeps unchanged: a loaded pose can differ from the saved one by
// those ulps (~1e-16), and save → load → save gives byte-identical files.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/mapping/mapping_types.h"

namespace dqo::mapping {

struct MapFileContents {
  gs::GaussianMap gaussians;  // every attribute: positions, log-scales, rotations, opacities,
                              // colours, confidences, stable, object IDs, types, birth keyframes
  std::vector<ObjectRecord> objects;
  std::vector<KeyframePose> keyframes;
  ObjectId next_object_id = 1;
  uint64_t params_hash = 0;  // hash of the parameters the map was built with (params_hash())
};

constexpr uint32_t kMapFileVersion = 1;

// Returns false with *error naming the file when it cannot be written (missing folder, full disk);
// an existing file at `path` is then left as it was.
bool save_map_file(const std::string& path, const MapFileContents& map, std::string* error);

// Returns nullopt with *error naming the file and saying why: "not a dqo_map map file", "map file
// version N, this build reads version 1", "truncated", "checksum mismatch", or a size or value that
// cannot be right.
std::optional<MapFileContents> load_map_file(const std::string& path, std::string* error);

// FNV-1a 64 of `text` (e.g. the YAML of the parameters): a map built with other parameters is told
// apart by its hash. Not cryptographic.
uint64_t params_hash(const std::string& text);

}  // namespace dqo::mapping
