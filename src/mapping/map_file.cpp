#include "dqo_map/mapping/map_file.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "dqo_map/common/atomic_file.h"

namespace dqo::mapping {

// The payload is the host's bytes; the file format is little-endian IEEE 754.
static_assert(std::numeric_limits<float>::is_iec559 && std::numeric_limits<double>::is_iec559,
              "the map file stores IEEE 754 floats");
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "map_file.cpp assumes a little-endian host"
#endif

namespace {

// 0x89 first (as PNG) so that no text tool takes the file for text; a trailing \n so that a
// transfer that rewrites line ends shows as a foreign file rather than a checksum failure.
constexpr char kMagic[8] = {'\x89', 'D', 'Q', 'O', 'M', 'A', 'P', '\n'};
constexpr size_t kHeaderBytes = 80;
constexpr size_t kChecksumBytes = 8;
constexpr uint64_t kGaussianBytes = 12 + 12 + 16 + 4 + 12 + 4 + 4 + 4 + 1 + 1;
constexpr uint64_t kObjectFixedBytes = 8 + 4 + 4 + 8 + 30 * 8 + 4;  // without the name's bytes
constexpr uint64_t kKeyframeBytes = 8 + 8 + 4 * 8 + 2 * 4 + 7 * 8;

constexpr uint64_t kFnvOffset = 14695981039346656037ull;
constexpr uint64_t kFnvPrime = 1099511628211ull;

uint64_t fnv1a64(const char* data, size_t n, uint64_t h = kFnvOffset) {
  for (size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(data[i]);
    h *= kFnvPrime;
  }
  return h;
}

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

std::string errno_text(int err) { return std::strerror(err); }

class ByteWriter {
 public:
  explicit ByteWriter(std::string* out) : out_(out) {}
  template <typename T>
  void put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    out_->append(b, sizeof(T));
  }
  template <typename T>
  void put_array(const std::vector<T>& v) {
    if (!v.empty()) out_->append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void put_bytes(const std::string& s) { out_->append(s); }
  void put_vector(const Eigen::Vector3d& v) {
    for (int i = 0; i < 3; ++i) put(v[i]);
  }
  void put_matrix(const Eigen::Matrix3d& m) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) put(m(r, c));
  }

 private:
  std::string* out_;
};

// Reads fixed-width values from a byte range; every read is bounds-checked and a failed one sticks,
// so a parse checks ok() once per record.
class ByteReader {
 public:
  ByteReader(const char* begin, const char* end) : p_(begin), end_(end) {}
  bool ok() const { return ok_; }
  size_t left() const { return static_cast<size_t>(end_ - p_); }
  template <typename T>
  T get() {
    T v{};
    if (!ok_ || left() < sizeof(T)) {
      ok_ = false;
      return v;
    }
    std::memcpy(&v, p_, sizeof(T));
    p_ += sizeof(T);
    return v;
  }
  template <typename T>
  std::vector<T> get_array(size_t n) {
    std::vector<T> v;
    if (!ok_ || left() / sizeof(T) < n) {
      ok_ = false;
      return v;
    }
    if (n == 0) return v;  // memcpy from/to a null pointer is undefined even for 0 bytes
    v.resize(n);
    std::memcpy(v.data(), p_, n * sizeof(T));
    p_ += n * sizeof(T);
    return v;
  }
  std::string get_string() {
    const uint32_t n = get<uint32_t>();
    if (!ok_ || left() < n) {
      ok_ = false;
      return {};
    }
    std::string s(p_, n);
    p_ += n;
    return s;
  }
  Eigen::Vector3d get_vector() {
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v[i] = get<double>();
    return v;
  }
  Eigen::Matrix3d get_matrix() {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = get<double>();
    return m;
  }

 private:
  const char* p_;
  const char* end_;
  bool ok_ = true;
};

// SE3's constructor renormalises, and renormalising a unit quaternion moves about a third of them
// by an ulp, so storing a pose's quaternion as it is would make save → load → save drift. Instead
// store a quaternion that the constructor keeps bit for bit, found by nudging the largest
// component (the one that moves the norm most per ulp) by up to 16 ulps: 4 million random unit
// quaternions all needed 4 at most. The loaded pose is then the stored quaternion exactly.
Eigen::Quaterniond storable_quaternion(const Eigen::Quaterniond& q) {
  const auto kept = [](const Eigen::Quaterniond& c) {
    return SE3(c, Eigen::Vector3d::Zero()).quaternion().coeffs() == c.coeffs();
  };
  if (kept(q)) return q;
  int k = 0;
  q.coeffs().cwiseAbs().maxCoeff(&k);
  for (int steps = 1; steps <= 16; ++steps) {
    for (const double direction : {1.0, -1.0}) {
      Eigen::Quaterniond c = q;
      double& v = c.coeffs()[k];
      for (int s = 0; s < steps; ++s) v = std::nextafter(v, direction * HUGE_VAL);
      if (kept(c)) return c;
    }
  }
  return q;  // not unit (or not finite) to begin with: stored as it is
}

void write_gaussians(const gs::GaussianMap& g, ByteWriter* w) {
  w->put_array(g.positions());
  w->put_array(g.log_scales());
  w->put_array(g.rotations());
  w->put_array(g.opacities());
  w->put_array(g.colours());
  w->put_array(g.confidences());
  w->put_array(g.object_ids_per_gaussian());
  w->put_array(g.birth_keyframes());
  w->put_array(g.types());
  w->put_array(g.stable());
}

void write_object(const ObjectRecord& o, ByteWriter* w) {
  w->put<uint64_t>(o.id);
  w->put<int32_t>(o.class_id);
  w->put<int32_t>(o.observations);
  w->put<double>(o.confidence);
  w->put_vector(o.quadric.centre());
  w->put_matrix(o.quadric.rotation());
  w->put_vector(o.quadric.semi_axes());
  w->put_vector(o.box.centre);
  w->put_matrix(o.box.rotation);
  w->put_vector(o.box.half_extents);
  w->put<uint32_t>(static_cast<uint32_t>(o.class_name.size()));
  w->put_bytes(o.class_name);
}

void write_keyframe(const KeyframePose& k, ByteWriter* w) {
  w->put<uint64_t>(k.id);
  w->put<double>(k.stamp);
  for (const double v : {k.camera.fx, k.camera.fy, k.camera.cx, k.camera.cy}) w->put(v);
  w->put<int32_t>(k.camera.width);
  w->put<int32_t>(k.camera.height);
  const Eigen::Quaterniond q = storable_quaternion(k.T_wc.quaternion());
  for (const double v : {q.w(), q.x(), q.y(), q.z()}) w->put(v);
  w->put_vector(k.T_wc.translation());
}

// Rebuilds the map through add() so that its invariants (equal lengths, one entry per Gaussian in
// every array) hold by construction, then sets what add() does not take.
bool read_gaussians(ByteReader* r, uint64_t count, gs::GaussianMap* map, std::string* why) {
  const size_t n = static_cast<size_t>(count);
  const auto pos = r->get_array<float>(3 * n);
  const auto log_scale = r->get_array<float>(3 * n);
  const auto rot = r->get_array<float>(4 * n);
  const auto opacity = r->get_array<float>(n);
  const auto colour = r->get_array<float>(3 * n);
  const auto confidence = r->get_array<float>(n);
  const auto object_id = r->get_array<uint32_t>(n);
  const auto birth = r->get_array<uint32_t>(n);
  const auto type = r->get_array<uint8_t>(n);
  const auto stable = r->get_array<uint8_t>(n);
  if (!r->ok()) {
    *why = "Gaussian section shorter than its count";
    return false;
  }
  map->reserve(n);
  for (size_t i = 0; i < n; ++i) {
    if (type[i] > static_cast<uint8_t>(gs::GaussianType::kTransparent)) {
      *why = "Gaussian " + std::to_string(i) + " has unknown type " + std::to_string(type[i]);
      return false;
    }
    gs::GaussianInit g;
    g.position = Eigen::Vector3f(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]);
    g.log_scale = Eigen::Vector3f(log_scale[3 * i], log_scale[3 * i + 1], log_scale[3 * i + 2]);
    g.rotation = Eigen::Vector4f(rot[4 * i], rot[4 * i + 1], rot[4 * i + 2], rot[4 * i + 3]);
    g.colour = Eigen::Vector3f(colour[3 * i], colour[3 * i + 1], colour[3 * i + 2]);
    g.opacity = opacity[i];
    g.object_id = object_id[i];
    g.type = static_cast<gs::GaussianType>(type[i]);
    g.birth_keyframe = birth[i];
    map->add(g);
  }
  // add() replaces a negative opacity by the type's; the file holds the value the map had.
  map->opacities() = opacity;
  map->confidences() = confidence;
  map->stable() = stable;
  return true;
}

ObjectRecord read_object(ByteReader* r) {
  ObjectRecord o;
  o.id = r->get<uint64_t>();
  o.class_id = r->get<int32_t>();
  o.observations = r->get<int32_t>();
  o.confidence = r->get<double>();
  const Eigen::Vector3d centre = r->get_vector();
  const Eigen::Matrix3d rotation = r->get_matrix();
  const Eigen::Vector3d semi_axes = r->get_vector();
  // from_params stores what it is given: the quadric comes back bit for bit.
  o.quadric = DualQuadric::from_params(centre, rotation, semi_axes);
  o.box.centre = r->get_vector();
  o.box.rotation = r->get_matrix();
  o.box.half_extents = r->get_vector();
  o.class_name = r->get_string();
  return o;
}

KeyframePose read_keyframe(ByteReader* r) {
  KeyframePose k;
  k.id = r->get<uint64_t>();
  k.stamp = r->get<double>();
  k.camera.fx = r->get<double>();
  k.camera.fy = r->get<double>();
  k.camera.cx = r->get<double>();
  k.camera.cy = r->get<double>();
  k.camera.width = r->get<int32_t>();
  k.camera.height = r->get<int32_t>();
  const double qw = r->get<double>(), qx = r->get<double>(), qy = r->get<double>(),
               qz = r->get<double>();
  const Eigen::Vector3d t = r->get_vector();
  k.T_wc = SE3(Eigen::Quaterniond(qw, qx, qy, qz), t);
  return k;
}

struct Header {
  uint32_t version = 0;
  uint32_t header_bytes = 0;
  uint64_t params_hash = 0;
  uint64_t next_object_id = 0;
  uint64_t counts[3] = {0, 0, 0};  // Gaussians, objects, keyframes
  uint64_t bytes[3] = {0, 0, 0};
};

constexpr const char* kSectionNames[3] = {"Gaussian", "object", "keyframe"};

}  // namespace

uint64_t params_hash(const std::string& text) { return fnv1a64(text.data(), text.size()); }

bool save_map_file(const std::string& path, const MapFileContents& map, std::string* error) {
  for (const ObjectRecord& o : map.objects) {
    if (o.class_name.size() > std::numeric_limits<uint32_t>::max())
      return fail(error, path + ": class name of object " + std::to_string(o.id) + " too long");
  }
  std::string sections[3];
  ByteWriter gaussians(&sections[0]), objects(&sections[1]), keyframes(&sections[2]);
  write_gaussians(map.gaussians, &gaussians);
  for (const ObjectRecord& o : map.objects) write_object(o, &objects);
  for (const KeyframePose& k : map.keyframes) write_keyframe(k, &keyframes);
  const uint64_t counts[3] = {map.gaussians.size(), map.objects.size(), map.keyframes.size()};

  std::string bytes;
  bytes.reserve(kHeaderBytes + sections[0].size() + sections[1].size() + sections[2].size() +
                kChecksumBytes);
  bytes.append(kMagic, sizeof(kMagic));
  ByteWriter w(&bytes);
  w.put<uint32_t>(kMapFileVersion);
  w.put<uint32_t>(kHeaderBytes);
  w.put<uint64_t>(map.params_hash);
  w.put<uint64_t>(map.next_object_id);
  for (int s = 0; s < 3; ++s) {
    w.put<uint64_t>(counts[s]);
    w.put<uint64_t>(sections[s].size());
  }
  for (std::string& s : sections) {
    bytes += s;
    std::string().swap(s);  // a large map is held twice at most, not three times
  }
  w.put<uint64_t>(fnv1a64(bytes.data(), bytes.size()));
  return write_file_atomically(path, bytes, error);
}

std::optional<MapFileContents> load_map_file(const std::string& path, std::string* error) {
  const auto bad = [&](const std::string& why) -> std::optional<MapFileContents> {
    fail(error, path + ": " + why);
    return std::nullopt;
  };
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return bad("is a folder, not a map file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return bad("cannot open: " + errno_text(errno));
  in.seekg(0, std::ios::end);
  const std::streamoff end = in.tellg();
  if (end < 0) return bad("cannot read its size");
  const uint64_t file_size = static_cast<uint64_t>(end);
  in.seekg(0, std::ios::beg);

  // The header alone first: a foreign or damaged file is refused before anything is allocated.
  char head[kHeaderBytes];
  const size_t head_size = static_cast<size_t>(std::min<uint64_t>(file_size, kHeaderBytes));
  in.read(head, static_cast<std::streamsize>(head_size));
  if (static_cast<size_t>(in.gcount()) != head_size) return bad("read error in the header");
  const std::string truncated = "truncated map file (" + std::to_string(file_size) + " bytes)";
  if (std::memcmp(head, kMagic, std::min(head_size, sizeof(kMagic))) != 0)
    return bad("not a dqo_map map file");
  if (head_size < sizeof(kMagic) + 4) return bad(truncated);
  Header h;
  ByteReader hr(head + sizeof(kMagic), head + head_size);
  h.version = hr.get<uint32_t>();
  if (h.version != kMapFileVersion)
    return bad("map file version " + std::to_string(h.version) + ", this build reads version " +
               std::to_string(kMapFileVersion));
  if (head_size < kHeaderBytes) return bad(truncated);
  h.header_bytes = hr.get<uint32_t>();
  h.params_hash = hr.get<uint64_t>();
  h.next_object_id = hr.get<uint64_t>();
  for (int s = 0; s < 3; ++s) {
    h.counts[s] = hr.get<uint64_t>();
    h.bytes[s] = hr.get<uint64_t>();
  }
  if (h.header_bytes != kHeaderBytes)
    return bad("corrupt header: header size " + std::to_string(h.header_bytes) + ", expected " +
               std::to_string(kHeaderBytes));

  // Counts against section sizes, then sizes against the file, in an order where no product or
  // sum can overflow: an absurd count fails here, before anything is allocated for it.
  const uint64_t record_bytes[3] = {kGaussianBytes, kObjectFixedBytes, kKeyframeBytes};
  uint64_t expected_size = kHeaderBytes + kChecksumBytes;
  for (int s = 0; s < 3; ++s) {
    const std::string name = kSectionNames[s];
    const bool fixed_size = s != 1;  // object records carry a class name of their own length
    if (h.counts[s] > h.bytes[s] / record_bytes[s] ||
        (fixed_size && h.bytes[s] != h.counts[s] * record_bytes[s]))
      return bad("corrupt header: " + std::to_string(h.counts[s]) + " " + name +
                 " records cannot take " + std::to_string(h.bytes[s]) + " bytes");
    if (h.bytes[s] > file_size)
      return bad(truncated + ", its " + name + " section alone claims " +
                 std::to_string(h.bytes[s]) + " bytes");
    expected_size += h.bytes[s];
  }
  if (file_size < expected_size)
    return bad(truncated + ", the header describes " + std::to_string(expected_size));
  if (file_size > expected_size)
    return bad(std::to_string(file_size - expected_size) + " bytes of trailing data after the " +
               std::to_string(expected_size) + " the header describes");

  std::string bytes(file_size, '\0');
  std::memcpy(bytes.data(), head, kHeaderBytes);
  in.read(bytes.data() + kHeaderBytes, static_cast<std::streamsize>(file_size - kHeaderBytes));
  if (static_cast<uint64_t>(in.gcount()) != file_size - kHeaderBytes)
    return bad("read error (the file shrank while it was read?)");
  const size_t body = file_size - kChecksumBytes;
  uint64_t stored_checksum = 0;
  std::memcpy(&stored_checksum, bytes.data() + body, kChecksumBytes);
  if (fnv1a64(bytes.data(), body) != stored_checksum)
    return bad("checksum mismatch: the file is damaged");

  MapFileContents map;
  map.params_hash = h.params_hash;
  map.next_object_id = h.next_object_id;
  const char* section = bytes.data() + kHeaderBytes;
  std::string why;
  ByteReader gr(section, section + h.bytes[0]);
  if (!read_gaussians(&gr, h.counts[0], &map.gaussians, &why)) return bad("corrupt: " + why);
  section += h.bytes[0];

  ByteReader obr(section, section + h.bytes[1]);
  map.objects.reserve(h.counts[1]);
  for (uint64_t i = 0; i < h.counts[1]; ++i) {
    map.objects.push_back(read_object(&obr));
    if (!obr.ok()) return bad("corrupt: object " + std::to_string(i) + " runs past its section");
  }
  if (obr.left() != 0)
    return bad("corrupt: " + std::to_string(obr.left()) + " unread bytes in the object section");
  section += h.bytes[1];

  ByteReader kr(section, section + h.bytes[2]);
  map.keyframes.reserve(h.counts[2]);
  for (uint64_t i = 0; i < h.counts[2]; ++i) map.keyframes.push_back(read_keyframe(&kr));
  if (!kr.ok() || kr.left() != 0) return bad("corrupt: keyframe section size");
  return map;
}

}  // namespace dqo::mapping
