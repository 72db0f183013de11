// Stage 2 of the CPU rasteriser: the visible Gaussians sorted once by depth (ties by index), then
// dealt into their tiles in that order, so that every tile's list is depth-ordered, as 3DGS's sort
// of (tile, depth) keys gives. The sort is a stable LSD radix sort on the depth's bit pattern
// (positive IEEE floats order like their bits) over an index-ordered input: ties keep index order,
// so the result depends on insertion order only through exact depth ties. Each Gaussian's pairs
// are listed too (TileBins::pair_first), for the backward pass's sums in a fixed order.

#include <algorithm>
#include <cstring>
#include <type_traits>

#include "dqo_map/gaussians/math/alpha.h"
#include "raster_internal.h"

namespace dqo::gs::detail {

namespace {

template <typename S>
using KeyOf = std::conditional_t<sizeof(S) == 4, uint32_t, uint64_t>;

// The positions in `ids` (ascending indices) ordered by their Gaussians' depth.
template <typename S>
std::vector<uint32_t> sort_by_depth(const std::vector<Splat<S>>& splats,
                                    const std::vector<uint32_t>& ids) {
  using Key = KeyOf<S>;
  static_assert(sizeof(Key) == sizeof(S), "key and scalar must have the same size");
  const size_t n = ids.size();
  std::vector<Key> keys(n), keys_tmp(n);
  std::vector<uint32_t> order(n), order_tmp(n);
  for (size_t i = 0; i < n; ++i) {
    std::memcpy(&keys[i], &splats[ids[i]].depth, sizeof(Key));
    order[i] = static_cast<uint32_t>(i);
  }
  for (unsigned shift = 0; shift < 8 * sizeof(Key); shift += 8) {
    size_t count[257] = {0};
    for (size_t i = 0; i < n; ++i) ++count[((keys[i] >> shift) & 0xff) + 1];
    if (count[((keys.empty() ? 0 : keys[0]) >> shift & 0xff) + 1] == n) continue;  // one bucket
    for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
    for (size_t i = 0; i < n; ++i) {
      const size_t dst = count[(keys[i] >> shift) & 0xff]++;
      keys_tmp[dst] = keys[i];
      order_tmp[dst] = order[i];
    }
    keys.swap(keys_tmp);
    order.swap(order_tmp);
  }
  return order;
}

}  // namespace

template <typename S>
void bin_gaussians(const ProjectedSet<S>& projected, int width, int height, TileBins* bins) {
  bins->tiles_x = (width + kTileSize - 1) / kTileSize;
  bins->tiles_y = (height + kTileSize - 1) / kTileSize;
  const size_t tiles = static_cast<size_t>(bins->tiles_x) * bins->tiles_y;

  const std::vector<uint32_t>& visible = projected.visible_ids;
  const std::vector<uint32_t> order = sort_by_depth(projected.splats, visible);

  // Only the tiles of its square that the Gaussian's α ≥ 1/255 ellipse reaches (the CUDA binning
  // asks the same question: math/alpha.h).
  auto reaches = [&](uint32_t id, int tx, int ty) {
    const Splat<S>& s = projected.splats[id];
    return ellipse_reaches_rect(s.conic, s.mean2d, s.opacity, S(tx * kTileSize), S(ty * kTileSize),
                                S(std::min(tx * kTileSize + kTileSize - 1, width - 1)),
                                S(std::min(ty * kTileSize + kTileSize - 1, height - 1)));
  };
  bins->offsets.assign(tiles + 1, 0);
  bins->pair_first.assign(visible.size() + 1, 0);
  std::vector<uint8_t> hit;  // per Gaussian of `order`, per tile of its rectangle
  std::vector<size_t> first_hit(order.size() + 1, 0);
  for (size_t k = 0; k < order.size(); ++k) {
    const uint32_t id = visible[order[k]];
    const PixelBox& r = projected.tile_rect[id];
    first_hit[k] = hit.size();
    for (int ty = r.y0; ty <= r.y1; ++ty)
      for (int tx = r.x0; tx <= r.x1; ++tx) {
        const bool h = reaches(id, tx, ty);
        hit.push_back(h ? 1 : 0);
        if (h) {
          ++bins->offsets[ty * bins->tiles_x + tx + 1];
          ++bins->pair_first[order[k] + 1];
        }
      }
  }
  for (size_t t = 0; t < tiles; ++t) bins->offsets[t + 1] += bins->offsets[t];
  for (size_t v = 0; v < visible.size(); ++v) bins->pair_first[v + 1] += bins->pair_first[v];
  bins->ids.resize(bins->offsets[tiles]);
  bins->pair_position.resize(bins->offsets[tiles]);
  bins->pair_tile.resize(bins->offsets[tiles]);
  std::vector<uint32_t> cursor(bins->offsets.begin(), bins->offsets.end() - 1);
  for (size_t k = 0; k < order.size(); ++k) {
    const uint32_t id = visible[order[k]];
    const PixelBox& r = projected.tile_rect[id];
    uint32_t pair = bins->pair_first[order[k]];
    size_t h = first_hit[k];
    for (int ty = r.y0; ty <= r.y1; ++ty)
      for (int tx = r.x0; tx <= r.x1; ++tx)
        if (hit[h++]) {
          const uint32_t tile = ty * bins->tiles_x + tx;
          const uint32_t position = cursor[tile]++;
          bins->ids[position] = id;
          bins->pair_position[pair] = position;
          bins->pair_tile[pair++] = tile;
        }
  }
}

template void bin_gaussians<float>(const ProjectedSet<float>&, int, int, TileBins*);
template void bin_gaussians<double>(const ProjectedSet<double>&, int, int, TileBins*);

}  // namespace dqo::gs::detail
