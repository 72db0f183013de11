#include "state_file.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <Eigen/Geometry>

#include "object_merge.h"

namespace dqo::objects {
namespace {

constexpr char kMagic[] = "dqo_object_state";
// 2: an `existence` line per object (the belief's log-odds). Version 1 files still load: their
// confirmed objects start at kVersion1Confirmed, candidates at even odds.
constexpr int kVersion = 2;
constexpr double kVersion1Confirmed = 4.0;

std::string num(double v) {
  char buf[40];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, r.ptr);
}

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

}  // namespace

bool write_state_file(const std::string& path, const std::map<ObjectId, MapObject>& objects,
                      ObjectId next_id, const std::string& map_id, std::string* error) {
  if (map_id.find('\n') != std::string::npos) return fail(error, path + ": a map ID cannot hold a line break");
  std::ostringstream out;
  out << kMagic << " " << kVersion << "\nnext_id " << next_id << "\nmap " << map_id << "\n";
  for (const auto& [id, o] : objects) {
    const Eigen::Quaterniond q(o.quadric.rotation());
    const Eigen::Vector3d& c = o.quadric.centre();
    const Eigen::Vector3d& a = o.quadric.semi_axes();
    out << "object " << id << " " << (o.state == ObjectState::kConfirmed ? "confirmed" : "candidate")
        << " " << o.class_id << " " << (o.has_quadric ? 1 : 0) << " " << (o.from_boxes ? 1 : 0);
    for (const double v : {c.x(), c.y(), c.z(), q.x(), q.y(), q.z(), q.w(), a.x(), a.y(), a.z()}) {
      out << " " << num(v);
    }
    out << " " << o.observation_count << " " << o.missed << " " << o.first_keyframe << " "
        << o.last_keyframe << " " << o.class_votes.size();
    for (const auto& [class_id, votes] : o.class_votes) out << " " << class_id << " " << num(votes);
    out << "\nname " << o.class_name << "\n";
    out << "existence " << num(o.existence) << "\n";
    if (o.has_box) {
      const Eigen::Quaterniond qb(o.box.rotation);
      out << "box";
      for (const double v : {o.box.centre.x(), o.box.centre.y(), o.box.centre.z(), qb.x(), qb.y(), qb.z(),
                             qb.w(), o.box.half_extents.x(), o.box.half_extents.y(), o.box.half_extents.z()}) {
        out << " " << num(v);
      }
      out << "\n";
    }
  }
  const std::string tmp = path + ".tmp";
  {
    std::ofstream file(tmp, std::ios::trunc);
    if (!file) return fail(error, path + ": cannot write " + tmp);
    file << out.str();
    file.flush();
    if (!file) return fail(error, path + ": writing " + tmp + " failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    return fail(error, path + ": cannot replace the file: " + ec.message());
  }
  return true;
}

bool read_state_file(const std::string& path, std::map<ObjectId, MapObject>* objects,
                     ObjectId* next_id, std::string* map_id, std::string* error) {
  std::ifstream in(path);
  std::string map;
  if (!in) return fail(error, path + ": cannot open the file");
  std::map<ObjectId, MapObject> read;
  ObjectId next = 0;
  bool have_next = false;
  std::string line;
  int line_no = 0;
  auto where = [&]() { return path + ":" + std::to_string(line_no) + ": "; };
  if (!std::getline(in, line)) return fail(error, path + ": empty file");
  ++line_no;
  {
    std::istringstream s(line);
    std::string magic;
    int version = 0;
    if (!(s >> magic >> version) || magic != kMagic) {
      return fail(error, where() + "not an object state file (expected '" + kMagic + " " + std::to_string(kVersion) + "')");
    }
    if (version != kVersion && version != 1) {
      return fail(error, where() + "unsupported version " + std::to_string(version));
    }
  }
  MapObject* last = nullptr;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "next_id") {
      if (!(s >> next) || next == 0) return fail(error, where() + "bad next_id");
      have_next = true;
    } else if (tag == "map") {
      map = line.size() > 4 ? line.substr(4) : std::string();
    } else if (tag == "object") {
      MapObject o;
      std::string state;
      int has_quadric = 0, from_boxes = 0;
      double v[10];
      size_t num_votes = 0;
      if (!(s >> o.id >> state >> o.class_id >> has_quadric >> from_boxes)) {
        return fail(error, where() + "malformed object line");
      }
      for (double& x : v) {
        if (!(s >> x) || !std::isfinite(x)) return fail(error, where() + "malformed object numbers");
      }
      if (!(s >> o.observation_count >> o.missed >> o.first_keyframe >> o.last_keyframe >> num_votes) ||
          num_votes > 100000) {
        return fail(error, where() + "malformed object counts");
      }
      for (size_t k = 0; k < num_votes; ++k) {
        int class_id = 0;
        double votes = 0.0;
        if (!(s >> class_id >> votes) || !std::isfinite(votes)) {
          return fail(error, where() + "malformed class votes");
        }
        o.class_votes[class_id] += votes;
      }
      std::string extra;
      if (s >> extra) return fail(error, where() + "unexpected text '" + extra + "'");
      if (o.id == 0 || read.count(o.id)) return fail(error, where() + "object ID 0 or listed twice");
      if (state != "confirmed" && state != "candidate") return fail(error, where() + "bad state '" + state + "'");
      o.state = state == "confirmed" ? ObjectState::kConfirmed : ObjectState::kCandidate;
      o.existence = o.state == ObjectState::kConfirmed ? kVersion1Confirmed : 0.0;
      o.has_quadric = has_quadric != 0;
      o.from_boxes = from_boxes != 0;
      const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
      const Eigen::Vector3d axes(v[7], v[8], v[9]);
      if (q.norm() < 1e-9 || !(axes.minCoeff() > 0.0)) {
        return fail(error, where() + "zero quaternion or non-positive semi-axis");
      }
      o.quadric = DualQuadric::from_params(Eigen::Vector3d(v[0], v[1], v[2]),
                                           q.normalized().toRotationMatrix(), axes);
      // The stored class wins over a recount (they differ only where votes tie).
      const int stored_class = o.class_id;
      update_class(&o);
      o.class_id = stored_class;
      last = &(read[o.id] = o);
    } else if (tag == "name") {
      if (!last) return fail(error, where() + "'name' before any object");
      last->class_name = line.size() > 5 ? line.substr(5) : std::string();
    } else if (tag == "existence") {
      double e = 0.0;
      if (!last || !(s >> e) || !std::isfinite(e)) return fail(error, where() + "malformed existence line");
      last->existence = e;
    } else if (tag == "box") {
      if (!last || last->has_box) return fail(error, where() + "'box' without its object");
      double v[10];
      for (double& x : v) {
        if (!(s >> x) || !std::isfinite(x)) return fail(error, where() + "malformed box numbers");
      }
      const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
      if (q.norm() < 1e-9 || v[7] < 0.0 || v[8] < 0.0 || v[9] < 0.0) {
        return fail(error, where() + "zero quaternion or negative half extent");
      }
      last->box.centre = Eigen::Vector3d(v[0], v[1], v[2]);
      last->box.rotation = q.normalized().toRotationMatrix();
      last->box.half_extents = Eigen::Vector3d(v[7], v[8], v[9]);
      last->has_box = true;
    } else {
      return fail(error, where() + "unknown line '" + tag + "'");
    }
  }
  if (!have_next) return fail(error, path + ": no next_id line");
  for (const auto& [id, o] : read) {
    if (id >= next) return fail(error, path + ": object " + std::to_string(id) + " is not below next_id");
  }
  *objects = std::move(read);
  *next_id = next;
  *map_id = map;
  return true;
}

}  // namespace dqo::objects
