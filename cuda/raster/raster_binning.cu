// Stage 2 of the CUDA rasteriser: each Gaussian's tiles as (tile, depth) keys, radix-sorted (CUB),
// then each tile's range of the sorted list. A tile's Gaussians come out in depth order with ties by
// index, as the CPU reference orders them (src/gaussians/raster_binning.cpp): depths are positive
// floats, whose bits sort as unsigned integers, and the sort is stable over pairs written in index
// order. The depth takes 28 bits of the key, not 32 (DepthKey): one radix pass fewer.

#include <cub/cub.cuh>

#include <algorithm>
#include <cstring>

#include "raster_cuda.h"

namespace dqo::cuda::detail {

namespace {

__global__ void emit_keys_kernel(size_t n, const DeviceSplat* splats, const TileRect* rects, const uint32_t* offsets,
                                 int width, int height, DepthKey dk, uint64_t* keys, uint32_t* values) {
  const int tiles_x = (width + kTileSize - 1) / kTileSize;
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const uint32_t begin = offsets[i], end = offsets[i + 1];
  if (begin == end) return;
  const TileRect t = rects[i];
  const float depth = splats[i].depth;
  const uint32_t bits = __float_as_uint(depth);
  const uint64_t depth_bits = min(static_cast<uint64_t>(bits > dk.base ? bits - dk.base : 0u), dk.max);
  uint32_t k = begin;
  const int w = t.x1 - t.x0 + 1;
  if (w * (t.y1 - t.y0 + 1) <= kReachedBits) {
    // The projection's answers, in the same (row by row) order.
    for (uint32_t m = t.reached; m != 0 && k < end; m &= m - 1) {
      const int b = __ffs(m) - 1;
      const int tx = t.x0 + b % w, ty = t.y0 + b / w;
      keys[k] = (static_cast<uint64_t>(ty * tiles_x + tx) << dk.bits) | depth_bits;
      values[k] = static_cast<uint32_t>(i);
      ++k;
    }
    return;
  }
  const DeviceSplat s = splats[i];
  for (int ty = t.y0; ty <= t.y1 && k < end; ++ty) {
    for (int tx = t.x0; tx <= t.x1 && k < end; ++tx) {
      if (!tile_reached(s, tx, ty, width, height)) continue;
      keys[k] = (static_cast<uint64_t>(ty * tiles_x + tx) << dk.bits) | depth_bits;
      values[k] = static_cast<uint32_t>(i);
      ++k;
    }
  }
}

__global__ void tile_ranges_kernel(size_t pairs, const uint64_t* keys, int depth_bits, uint2* ranges) {
  const size_t k = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= pairs) return;
  const uint32_t tile = static_cast<uint32_t>(keys[k] >> depth_bits);
  if (k == 0 || static_cast<uint32_t>(keys[k - 1] >> depth_bits) != tile) ranges[tile].x = static_cast<uint32_t>(k);
  if (k + 1 == pairs || static_cast<uint32_t>(keys[k + 1] >> depth_bits) != tile)
    ranges[tile].y = static_cast<uint32_t>(k + 1);
}

__global__ void tile_work_kernel(size_t tiles, const uint2* ranges, uint32_t* keys, uint32_t* ids) {
  const size_t t = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= tiles) return;
  keys[t] = ranges[t].y - ranges[t].x;
  ids[t] = static_cast<uint32_t>(t);
}

// Grows *temp to `bytes` (device memory kept between calls: no allocation per frame once warm).
// A failed allocation is returned: CUB handed a null buffer would only report its size and sort
// nothing.
cudaError_t ensure(void** temp, size_t* temp_bytes, size_t bytes) {
  if (bytes <= *temp_bytes && *temp) return cudaSuccess;
  if (*temp) cudaFree(*temp);
  *temp = nullptr;
  *temp_bytes = 0;
  const cudaError_t err = cudaMalloc(temp, std::max<size_t>(bytes, 1));
  if (err == cudaSuccess) *temp_bytes = bytes;
  return err;
}

}  // namespace

cudaError_t exclusive_scan(size_t n, const uint32_t* tile_count, uint32_t* offsets, void** temp,
                           size_t* temp_bytes, cudaStream_t stream) {
  // Scans n + 1 entries: tile_count[n] is 0 (the caller's), so offsets[n] is the total.
  size_t bytes = 0;
  cudaError_t err =
      cub::DeviceScan::ExclusiveSum(nullptr, bytes, tile_count, offsets, static_cast<int>(n + 1), stream);
  if (err == cudaSuccess) err = ensure(temp, temp_bytes, bytes);
  if (err != cudaSuccess) return err;
  return cub::DeviceScan::ExclusiveSum(*temp, bytes, tile_count, offsets, static_cast<int>(n + 1), stream);
}

DepthKey depth_key_for(float near) {
  // Below ~1e-30 m there is no bound worth shifting by: the float's bits as they are.
  if (!(near >= 1e-30f)) return DepthKey{0u, 32, 0xffffffffull};
  uint32_t bits;
  std::memcpy(&bits, &near, sizeof bits);
  return DepthKey{bits & 0xff800000u, 28, (uint64_t{1} << 28) - 1};
}

void launch_emit_keys(size_t n, const DeviceSplat* splats, const TileRect* rects, const uint32_t* offsets,
                      int width, int height, const DepthKey& dk, uint64_t* keys, uint32_t* values,
                      cudaStream_t stream) {
  if (n == 0) return;
  constexpr int kBlock = 256;
  emit_keys_kernel<<<static_cast<unsigned>((n + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      n, splats, rects, offsets, width, height, dk, keys, values);
}

cudaError_t sort_pairs(size_t pairs, int key_bits, const uint64_t* keys_in, uint64_t* keys_out,
                       const uint32_t* values_in, uint32_t* values_out, void** temp, size_t* temp_bytes,
                       cudaStream_t stream) {
  if (pairs == 0) return cudaSuccess;
  // Only the bits in use: the depth's and as many of tile as there are tiles.
  const int end_bit = key_bits;
  size_t bytes = 0;
  cudaError_t err = cub::DeviceRadixSort::SortPairs(nullptr, bytes, keys_in, keys_out, values_in, values_out,
                                                    static_cast<int>(pairs), 0, end_bit, stream);
  if (err == cudaSuccess) err = ensure(temp, temp_bytes, bytes);
  if (err != cudaSuccess) return err;
  return cub::DeviceRadixSort::SortPairs(*temp, bytes, keys_in, keys_out, values_in, values_out,
                                         static_cast<int>(pairs), 0, end_bit, stream);
}

cudaError_t order_tiles(size_t tiles, const uint2* ranges, uint32_t* keys, uint32_t* ids, uint32_t* keys_out,
                        uint32_t* tile_order, void** temp, size_t* temp_bytes, cudaStream_t stream) {
  if (tiles == 0) return cudaSuccess;
  constexpr int kBlock = 256;
  tile_work_kernel<<<static_cast<unsigned>((tiles + kBlock - 1) / kBlock), kBlock, 0, stream>>>(tiles, ranges, keys,
                                                                                                ids);
  size_t bytes = 0;
  const int items = static_cast<int>(tiles);
  cudaError_t err = cub::DeviceRadixSort::SortPairsDescending(nullptr, bytes, keys, keys_out, ids, tile_order, items,
                                                              0, 32, stream);
  if (err == cudaSuccess) err = ensure(temp, temp_bytes, bytes);
  if (err != cudaSuccess) return err;
  return cub::DeviceRadixSort::SortPairsDescending(*temp, bytes, keys, keys_out, ids, tile_order, items, 0, 32,
                                                   stream);
}

void launch_tile_ranges(size_t pairs, const uint64_t* sorted_keys, int depth_bits, uint2* ranges,
                        cudaStream_t stream) {
  if (pairs == 0) return;
  constexpr int kBlock = 256;
  tile_ranges_kernel<<<static_cast<unsigned>((pairs + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      pairs, sorted_keys, depth_bits, ranges);
}

}  // namespace dqo::cuda::detail
