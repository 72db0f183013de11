#include "dqo_map/gaussians/gaussian_ply.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "dqo_map/common/atomic_file.h"

namespace dqo::gs {

// The writer copies the host's float and integer bytes straight into a little-endian file.
static_assert(std::numeric_limits<float>::is_iec559 && std::numeric_limits<double>::is_iec559,
              "PLY floats are IEEE 754");
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "gaussian_ply.cpp assumes a little-endian host"
#endif

namespace {

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

std::string errno_text(int err) { return std::strerror(err); }

template <typename T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

// ---- Reading ------------------------------------------------------------------------------------

enum class PlyFormat { kAscii, kBinaryLittle, kBinaryBig };

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<PlyType> parse_type(const std::string& s) {
  if (s == "char" || s == "int8") return PlyType::kInt8;
  if (s == "uchar" || s == "uint8") return PlyType::kUint8;
  if (s == "short" || s == "int16") return PlyType::kInt16;
  if (s == "ushort" || s == "uint16") return PlyType::kUint16;
  if (s == "int" || s == "int32") return PlyType::kInt32;
  if (s == "uint" || s == "uint32") return PlyType::kUint32;
  if (s == "float" || s == "float32") return PlyType::kFloat32;
  if (s == "double" || s == "float64") return PlyType::kFloat64;
  return std::nullopt;
}

size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::kInt8:
    case PlyType::kUint8: return 1;
    case PlyType::kInt16:
    case PlyType::kUint16: return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32: return 4;
    case PlyType::kFloat64: return 8;
  }
  return 0;
}

template <typename T>
T load_as(const char* p, bool swap) {
  char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// Every PLY scalar type is exactly representable as a double, so one decoder serves them all.
double decode(const char* p, PlyType t, bool swap) {
  switch (t) {
    case PlyType::kInt8: return load_as<int8_t>(p, swap);
    case PlyType::kUint8: return load_as<uint8_t>(p, swap);
    case PlyType::kInt16: return load_as<int16_t>(p, swap);
    case PlyType::kUint16: return load_as<uint16_t>(p, swap);
    case PlyType::kInt32: return load_as<int32_t>(p, swap);
    case PlyType::kUint32: return load_as<uint32_t>(p, swap);
    case PlyType::kFloat32: return load_as<float>(p, swap);
    case PlyType::kFloat64: return load_as<double>(p, swap);
  }
  return 0.0;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;
  bool is_list = false;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
};

std::vector<std::string> split_words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

// Reads the header up to and including "end_header"; leaves `in` at the first data byte.
std::optional<PlyHeader> read_header(std::istream& in, const std::string& path, std::string* error) {
  const auto bad = [&](const std::string& why) -> std::optional<PlyHeader> {
    fail(error, path + ": " + why);
    return std::nullopt;
  };
  // The magic first, so that a large binary file without newlines is not read as one long line.
  char magic[4] = {0, 0, 0, 0};
  in.read(magic, 4);
  if (in.gcount() < 4 || std::memcmp(magic, "ply", 3) != 0 || (magic[3] != '\n' && magic[3] != '\r'))
    return bad("not a PLY file (it does not start with \"ply\")");
  if (magic[3] == '\r' && in.peek() == '\n') in.get();

  PlyHeader header;
  bool have_format = false;
  for (int line_no = 2;; ++line_no) {
    // Bounded lines: a damaged header fails here instead of reading the whole file as one line.
    std::array<char, 4096> buffer;
    in.getline(buffer.data(), buffer.size());
    if (in.eof() && in.gcount() == 0) return bad("truncated PLY header (no end_header)");
    if (in.fail()) return bad("PLY header line " + std::to_string(line_no) + " too long");
    std::string line(buffer.data());
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // A header line cut by the end of the file (only end_header may lack its newline).
    if (in.eof() && line != "end_header") return bad("truncated PLY header (no end_header)");
    const std::vector<std::string> w = split_words(line);
    const std::string where = "PLY header line " + std::to_string(line_no) + ": ";
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") break;
    if (w[0] == "format") {
      if (w.size() != 3) return bad(where + "malformed format line");
      if (w[1] == "ascii") header.format = PlyFormat::kAscii;
      else if (w[1] == "binary_little_endian") header.format = PlyFormat::kBinaryLittle;
      else if (w[1] == "binary_big_endian") header.format = PlyFormat::kBinaryBig;
      else return bad(where + "unknown format \"" + w[1] + "\"");
      have_format = true;
    } else if (w[0] == "element") {
      if (w.size() != 3) return bad(where + "malformed element line");
      char* end = nullptr;
      errno = 0;
      const unsigned long long count = std::strtoull(w[2].c_str(), &end, 10);
      if (w[2][0] == '-' || *end != '\0' || errno == ERANGE)
        return bad(where + "bad element count \"" + w[2] + "\"");
      header.elements.push_back(PlyElement{w[1], count, {}});
    } else if (w[0] == "property") {
      if (header.elements.empty()) return bad(where + "property before any element");
      PlyProperty p;
      if (w.size() == 5 && w[1] == "list") {
        const auto count_type = parse_type(w[2]);
        const auto item_type = parse_type(w[3]);
        if (!count_type || !item_type) return bad(where + "unknown property type");
        p.is_list = true;
        p.type = *item_type;
        p.name = w[4];
      } else if (w.size() == 3) {
        const auto type = parse_type(w[1]);
        if (!type) return bad(where + "unknown property type \"" + w[1] + "\"");
        p.type = *type;
        p.name = w[2];
      } else {
        return bad(where + "malformed property line");
      }
      header.elements.back().properties.push_back(p);
    } else {
      return bad(where + "unexpected \"" + w[0] + "\"");
    }
  }
  if (!have_format) return bad("PLY header has no format line");
  return header;
}

// Where each attribute the map needs sits among the vertex properties.
struct VertexLayout {
  static constexpr int kRequired = 14;
  static constexpr std::array<const char*, kRequired> kNames = {
      "x",       "y",       "z",       "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
      "scale_0", "scale_1", "scale_2", "rot_0",  "rot_1",  "rot_2",  "rot_3"};
  std::array<int, kRequired> index{};  // property index of each required attribute
  int object_id = -1;                  // -1: absent, every Gaussian to the background
};

// Turns one vertex's decoded values (by property index) into a Gaussian.
bool to_gaussian(const std::vector<double>& values, const VertexLayout& layout, uint64_t vertex,
                 const std::string& path, GaussianInit* g, std::string* error) {
  const auto v = [&](int k) { return values[static_cast<size_t>(layout.index[k])]; };
  g->position = Eigen::Vector3f(float(v(0)), float(v(1)), float(v(2)));
  for (int c = 0; c < 3; ++c) g->colour[c] = static_cast<float>(0.5 + kShC0 * v(3 + c));
  g->opacity = static_cast<float>(1.0 / (1.0 + std::exp(-v(6))));
  g->log_scale = Eigen::Vector3f(float(v(7)), float(v(8)), float(v(9)));
  g->rotation = Eigen::Vector4f(float(v(10)), float(v(11)), float(v(12)), float(v(13)));
  g->type = GaussianType::kOpaque;
  g->object_id = 0;
  if (layout.object_id >= 0) {
    const double id = values[static_cast<size_t>(layout.object_id)];
    if (!(id >= 0.0 && id <= 4294967295.0 && id == std::floor(id)))
      return fail(error, path + ": vertex " + std::to_string(vertex) + ": object_id " +
                             std::to_string(id) + " is not a 32-bit unsigned integer");
    g->object_id = static_cast<uint32_t>(id);
  }
  return true;
}

bool read_binary_vertices(std::istream& in, uint64_t bytes_left, const PlyElement& vertex,
                          const VertexLayout& layout, bool swap, const std::string& path,
                          GaussianMap* map, std::string* error) {
  std::vector<size_t> offset(vertex.properties.size());
  size_t stride = 0;
  for (size_t k = 0; k < vertex.properties.size(); ++k) {
    offset[k] = stride;
    stride += type_size(vertex.properties[k].type);
  }
  // Checked before any allocation, so that an absurd count in a damaged header fails cleanly.
  if (vertex.count > bytes_left / stride)
    return fail(error, path + ": truncated: " + std::to_string(vertex.count) + " vertices of " +
                           std::to_string(stride) + " bytes need " +
                           std::to_string(vertex.count * stride) + " bytes, the file holds " +
                           std::to_string(bytes_left) + " after its header");
  map->reserve(vertex.count);
  constexpr uint64_t kChunk = 16384;  // vertices per read: bounded memory for any file size
  std::vector<char> chunk;
  std::vector<double> values(vertex.properties.size());
  std::vector<size_t> needed(layout.index.begin(), layout.index.end());
  if (layout.object_id >= 0) needed.push_back(static_cast<size_t>(layout.object_id));
  for (uint64_t first = 0; first < vertex.count; first += kChunk) {
    const uint64_t n = std::min(kChunk, vertex.count - first);
    chunk.resize(n * stride);
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    if (static_cast<size_t>(in.gcount()) != chunk.size())
      return fail(error, path + ": truncated: read error after " + std::to_string(first) +
                             " vertices");
    for (uint64_t i = 0; i < n; ++i) {
      const char* row = chunk.data() + i * stride;
      for (size_t k : needed) values[k] = decode(row + offset[k], vertex.properties[k].type, swap);
      GaussianInit g;
      if (!to_gaussian(values, layout, first + i, path, &g, error)) return false;
      map->add(g);
    }
  }
  return true;
}

bool read_ascii_vertices(std::istream& in, uint64_t lines_to_skip, uint64_t bytes_left,
                         const PlyElement& vertex, const VertexLayout& layout,
                         const std::string& path, GaussianMap* map, std::string* error) {
  std::string line;
  for (uint64_t i = 0; i < lines_to_skip; ++i) {
    if (!std::getline(in, line))
      return fail(error, path + ": truncated: the file ends before the vertex element");
  }
  // Each ascii value takes at least two bytes (a digit and a separator).
  map->reserve(std::min<uint64_t>(vertex.count, bytes_left / (2 * vertex.properties.size())));
  std::vector<double> values(vertex.properties.size());
  for (uint64_t i = 0; i < vertex.count; ++i) {
    if (!std::getline(in, line))
      return fail(error, path + ": truncated: " + std::to_string(i) + " of " +
                             std::to_string(vertex.count) + " vertices");
    const char* p = line.c_str();
    for (size_t k = 0; k < values.size(); ++k) {
      char* end = nullptr;
      values[k] = std::strtod(p, &end);
      if (end == p)
        return fail(error, path + ": vertex " + std::to_string(i) + ": expected " +
                               std::to_string(values.size()) + " numbers, found " +
                               std::to_string(k));
      p = end;
    }
    GaussianInit g;
    if (!to_gaussian(values, layout, i, path, &g, error)) return false;
    map->add(g);
  }
  return true;
}

}  // namespace

bool save_gaussians_ply(const std::string& path, const GaussianMap& map,
                        const std::vector<uint32_t>* indices, std::string* error) {
  const size_t n = indices ? indices->size() : map.size();
  if (indices) {
    for (uint32_t i : *indices) {
      if (i >= map.size())
        return fail(error, path + ": Gaussian index " + std::to_string(i) +
                               " out of range (the map has " + std::to_string(map.size()) + ")");
    }
  }
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\n"
         << "comment dqo_map Gaussians: 3DGS layout, degree-0 SH, object_id per Gaussian\n"
         << "element vertex " << n << "\n";
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                           "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"}) {
    header << "property float " << name << "\n";
  }
  header << "property uint object_id\nend_header\n";

  std::string bytes = header.str();
  constexpr size_t kVertexBytes = 17 * sizeof(float) + sizeof(uint32_t);
  bytes.reserve(bytes.size() + n * kVertexBytes);
  const auto& pos = map.positions();
  const auto& log_scale = map.log_scales();
  const auto& rot = map.rotations();
  const auto& colour = map.colours();
  const auto& opacity = map.opacities();
  const auto& ids = map.object_ids_per_gaussian();
  for (size_t k = 0; k < n; ++k) {
    const size_t i = indices ? (*indices)[k] : k;
    for (int c = 0; c < 3; ++c) put(bytes, pos[3 * i + c]);
    for (int c = 0; c < 3; ++c) put(bytes, 0.f);
    for (int c = 0; c < 3; ++c)
      put(bytes, static_cast<float>((double(colour[3 * i + c]) - 0.5) / kShC0));
    // Clamped so that an opacity of exactly 0 or 1 gives a finite logit (±27.6), which the
    // sigmoid maps back to the same float.
    const double a = std::clamp(double(opacity[i]), 1e-12, 1.0 - 1e-12);
    put(bytes, static_cast<float>(std::isnan(opacity[i]) ? opacity[i] : std::log(a / (1.0 - a))));
    for (int c = 0; c < 3; ++c) put(bytes, log_scale[3 * i + c]);
    for (int c = 0; c < 4; ++c) put(bytes, rot[4 * i + c]);
    put(bytes, ids[i]);
  }
  return write_file_atomically(path, bytes, error);
}

std::optional<GaussianMap> load_gaussians_ply(const std::string& path, std::string* error) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    fail(error, path + ": is a folder, not a PLY file");
    return std::nullopt;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    fail(error, path + ": cannot open: " + errno_text(errno));
    return std::nullopt;
  }
  in.seekg(0, std::ios::end);
  const std::streamoff file_size = in.tellg();
  if (file_size < 0) {
    fail(error, path + ": cannot read its size");
    return std::nullopt;
  }
  in.seekg(0, std::ios::beg);

  const std::optional<PlyHeader> header = read_header(in, path, error);
  if (!header) return std::nullopt;
  std::streamoff data_start = in.tellg();
  if (data_start < 0) {  // the header ended the file (no newline after end_header): no data
    in.clear();
    data_start = file_size;
  }
  uint64_t bytes_left = static_cast<uint64_t>(file_size - data_start);

  // Elements before "vertex" are skipped: by size in binary files, by lines in ascii ones.
  const PlyElement* vertex = nullptr;
  uint64_t lines_to_skip = 0;
  for (const PlyElement& e : header->elements) {
    if (e.name == "vertex") {
      vertex = &e;
      break;
    }
    if (header->format == PlyFormat::kAscii) {
      lines_to_skip += e.count;
      continue;
    }
    uint64_t stride = 0;
    for (const PlyProperty& p : e.properties) {
      if (p.is_list) {
        fail(error, path + ": element \"" + e.name +
                        "\" with list properties before the vertex element: not supported");
        return std::nullopt;
      }
      stride += type_size(p.type);
    }
    if (stride > 0 && e.count > bytes_left / stride) {
      fail(error, path + ": truncated: element \"" + e.name + "\" runs past the end of the file");
      return std::nullopt;
    }
    bytes_left -= e.count * stride;
    in.seekg(static_cast<std::streamoff>(e.count * stride), std::ios::cur);
  }
  if (!vertex) {
    fail(error, path + ": PLY file has no vertex element");
    return std::nullopt;
  }

  VertexLayout layout;
  layout.index.fill(-1);
  for (size_t k = 0; k < vertex->properties.size(); ++k) {
    const PlyProperty& p = vertex->properties[k];
    for (int r = 0; r < VertexLayout::kRequired; ++r) {
      if (p.name == VertexLayout::kNames[r] && layout.index[r] < 0) layout.index[r] = int(k);
    }
    if (p.name == "object_id" && layout.object_id < 0) layout.object_id = int(k);
    if (p.is_list) {
      fail(error, path + ": vertex property \"" + p.name + "\" is a list: not a 3DGS PLY");
      return std::nullopt;
    }
  }
  std::string missing;
  for (int r = 0; r < VertexLayout::kRequired; ++r) {
    if (layout.index[r] < 0) missing += std::string(missing.empty() ? "" : " ") + VertexLayout::kNames[r];
  }
  if (!missing.empty()) {
    fail(error, path + ": not a 3DGS Gaussian PLY: vertex property missing: " + missing);
    return std::nullopt;
  }

  GaussianMap map;
  const bool ok =
      header->format == PlyFormat::kAscii
          ? read_ascii_vertices(in, lines_to_skip, bytes_left, *vertex, layout, path, &map, error)
          : read_binary_vertices(in, bytes_left, *vertex, layout,
                                 header->format == PlyFormat::kBinaryBig, path, &map, error);
  if (!ok) return std::nullopt;
  return map;
}

}  // namespace dqo::gs
