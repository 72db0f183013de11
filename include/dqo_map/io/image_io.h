#pragma once
// Image files (through OpenCV, which stays inside io/'s .cpp files) and the uint16 depth encoding
// of the dataset formats. Colour images are RGB in memory; the BGR order of OpenCV is converted at
// this boundary and nowhere else.

#include <cstdint>
#include <optional>
#include <string>

#include "dqo_map/common/image.h"

namespace dqo {

// Lossless PNG. 8-bit images with 1 (grey), 3 (RGB) or 4 (RGBA) channels; 16-bit images with 1 or
// 3 (RGB) channels. The path must end in ".png". False (and *error set) when the image is empty,
// has an unsupported channel count or the file cannot be written.
bool write_png(const std::string& path, const Image<uint8_t>& image, std::string* error = nullptr);
bool write_png(const std::string& path, const Image<uint16_t>& image,
               std::string* error = nullptr);

// Lossy JPEG of an RGB (or grey) image, quality 0..100; for Replica-like output and fixtures.
bool write_jpeg(const std::string& path, const Image<uint8_t>& image, int quality = 95,
                std::string* error = nullptr);

// Any 8-bit image OpenCV decodes (PNG, JPEG, ...) as 3-channel RGB: grey is replicated, alpha is
// dropped. 16-bit files are refused (no silent rescaling).
std::optional<ImageRgb8> read_rgb_image(const std::string& path, std::string* error = nullptr);

// A single-channel 16-bit PNG (depth, instance IDs), values unchanged.
std::optional<Image<uint16_t>> read_png_u16(const std::string& path,
                                            std::string* error = nullptr);

// Depth encoding of the dataset formats: stored = round(depth_m * depth_scale), 0 = no
// measurement. Depths that are not finite, not positive, or whose stored value would be 0 or
// exceed 65535 are stored as 0 (invalid) rather than clamped: a clamped value would be a wrong
// measurement.
Image<uint16_t> depth_to_u16(const DepthImage& depth, double depth_scale);

// stored / depth_scale in metres (computed in double, then rounded to float); 0 stays 0.
DepthImage depth_from_u16(const Image<uint16_t>& stored, double depth_scale);

// depth_from_u16(depth_to_u16(depth)): exactly what a reader returns for depth a writer was given.
DepthImage quantise_depth(const DepthImage& depth, double depth_scale);

}  // namespace dqo
