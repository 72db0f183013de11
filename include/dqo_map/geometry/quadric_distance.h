#pragma once
// Similarity of two ellipsoids, for the fine association step and the occlusion merge
// (METHOD.md §2.4, §2.5). Both compare the ellipsoids as Gaussians N(mu, S) with S the shape matrix
// R diag(a², b², c²) Rᵀ (DualQuadric::shape_matrix), so centre and shape enter in the same units.

#include "dqo_map/geometry/dual_quadric.h"

namespace dqo {

// The paper's QD = exp(−tau (‖mu_a − mu_b‖₂ + ‖S_a − S_b‖_F)): 1 for identical ellipsoids, falling
// towards 0 as the centres or shapes move apart. tau (1/m) sets how fast; note that the shape term
// is in m², so it weighs size differences of large objects more than of small ones.
double quadric_distance(const DualQuadric& a, const DualQuadric& b, double tau);

// Squared 2-Wasserstein distance between N(mu_a, S_a) and N(mu_b, S_b):
// ‖mu_a − mu_b‖² + tr(S_a + S_b − 2 (S_b^½ S_a S_b^½)^½), in m² (never negative).
double wasserstein_distance_sq(const DualQuadric& a, const DualQuadric& b);

// The released code's variant of QD: exp(−sqrt(W₂²) / C), C in metres.
double wasserstein_similarity(const DualQuadric& a, const DualQuadric& b, double C = 10.0);

enum class QuadricDistanceKind { kQD, kWasserstein };

struct QuadricDistanceParams {
  QuadricDistanceKind kind = QuadricDistanceKind::kQD;
  double tau = 1.0;             // for kQD
  double wasserstein_c = 10.0;  // for kWasserstein
};

// The similarity (in (0, 1], 1 = identical) that `params.kind` selects.
double quadric_similarity(const DualQuadric& a, const DualQuadric& b,
                          const QuadricDistanceParams& params);

}  // namespace dqo
