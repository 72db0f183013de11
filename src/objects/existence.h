#pragma once
// Stage: the evidence a keyframe gives about whether an object exists (ExistenceParams,
// object_params.h), and the belief update. Depth decides what a miss means: the keyframe's depth
// along rays through the object's ellipsoid either stops before it (an occluder: the keyframe says
// nothing), on it (a surface where the object should be: the detector missed something that is
// there) or beyond it (free space where the object is claimed: strong evidence of absence).
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

// What the depth inside an object's projected box says, from rays through a 5×5 grid over the
// box's central half that meet the ellipsoid.
struct DepthEvidenceCounts {
  int rays = 0;      // grid rays that meet the ellipsoid
  int valid = 0;     // ... of those, with a valid depth
  int nearer = 0;    // depth before the ellipsoid's entry (an occluder)
  int surface = 0;   // depth between entry and exit (a surface where the object is)
  int beyond = 0;    // depth past the exit (free space through the object)
};

enum class MissKind {
  kOccluded,   // most valid rays stop before the object: not visible, no evidence
  kSupported,  // the depth shows a surface inside the ellipsoid (or there is no depth)
  kFreeSpace,  // the depth sees through the ellipsoid
  kExplained,  // a detection where it should be went to another object: a plain miss, the surface
               // it shows is that object's (a duplicate of one object decays, not lingers)
};

// `tolerance`: metres of depth noise on either side of the ellipsoid (plus 1 % of the depth).
DepthEvidenceCounts depth_evidence(const DualQuadric& quadric, const Box2d& projected,
                                   const PinholeCamera& camera, const SE3& T_wc,
                                   const DepthView& depth, double tolerance = 0.05);

// No depth (data == nullptr) or no valid ray: kSupported (nothing contradicts the object).
MissKind classify_miss(const DepthEvidenceCounts& counts, const ExistenceParams& params);

// The log-odds after a detection or a miss of that kind, clamped to ±max_log_odds. A detection of
// score s is right with probability s (a calibrated detector): its likelihood ratio mixes the
// detector model's r / f with no evidence, 1 + s (r / f − 1); score 1 gives log(r / f).
double after_detection(double log_odds, const std::string& class_name, double score, const ExistenceParams& params);
double after_miss(double log_odds, MissKind kind, const std::string& class_name, const ExistenceParams& params);

double logit(double p);

}  // namespace dqo::objects
