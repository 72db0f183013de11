#pragma once
// Image metrics of a rendered view against its RGB-D frame: PSNR, depth L1 on valid pixels and
// agreement of the rendered object IDs with a label/instance image on object pixels. Used by the
// tests and bench_mapping.

#include <cstdint>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::gs {

// 10 log10(1 / MSE) over all pixels and channels, colours in [0, 1]. `mask` (width·height, non-zero
// = counted) may be empty. Returns +inf for a perfect match, NaN when no pixel counts.
double psnr(const RenderOutput& out, const ImageRgb8& target,
            const std::vector<uint8_t>& mask = {});

// Mean |d̂ − d| in metres over the pixels with a valid measurement (finite, > 0) and non-zero mask.
double depth_l1(const RenderOutput& out, const DepthImage& target,
                const std::vector<uint8_t>& mask = {});

// Fraction of object pixels (label > 0) whose rendered dominant ID equals the label. NaN when the
// image has no object pixel.
double id_agreement(const RenderOutput& out, const Image<uint32_t>& labels);
double id_agreement(const RenderOutput& out, const InstanceImage& instance);

}  // namespace dqo::gs
