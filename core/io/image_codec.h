// PNG and JPEG image files to and from cv::Mat, with libpng and libjpeg-turbo
// (OpenCV's imgcodecs links GDAL and some hundred shared libraries whose
// loading alone takes ~0.08 s per process start).
//
// Pixel layout: OpenCV's (rows x cols, channels interleaved, colour as BGR /
// BGRA). The stored pixels are returned as they are: no EXIF orientation, no
// gamma or colour-profile conversion (COLMAP's keypoints refer to these).
//
// Failures: ReadImageFile returns an empty Mat (and says why in `error`) for
// a file that cannot be opened or is not a PNG / JPEG it can decode; callers
// turn that into an InputError naming the file. Encoding an unsupported Mat
// type is a programming error (InternalError).
#pragma once

#include <string>

#include <opencv2/core/mat.hpp>

namespace lisfm {

enum class ImageReadMode {
  // PNG: its bit depth (8 or 16; 1, 2, 4-bit grey and palettes expand to 8)
  // and channels (1 grey, 2 grey + alpha, 3 BGR, 4 BGRA); JPEG: 8-bit grey
  // (1 channel) or BGR (3 channels).
  kUnchanged,
  // 8-bit BGR always: grey replicated, alpha dropped, 16-bit samples keep
  // their high byte (as cv::IMREAD_COLOR).
  kColor,
};

// The file type is taken from its first bytes, not its name.
cv::Mat ReadImageFile(const std::string& path, ImageReadMode mode, std::string* error = nullptr);

// PNG file bytes of `image`: CV_8UC1 / CV_8UC3 (BGR) / CV_8UC4 (BGRA) /
// CV_16UC1 / CV_16UC3 (BGR); zlib compression level 0..9.
std::string EncodePng(const cv::Mat& image, int compression = 1);

// Writes EncodePng(image, compression) to `path` (replacing it atomically).
// False when the file cannot be written.
bool WritePngFile(const std::string& path, const cv::Mat& image, int compression = 1);

}  // namespace lisfm
