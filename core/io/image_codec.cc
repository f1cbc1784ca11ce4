#include "core/io/image_codec.h"

#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <vector>

#include <jpeglib.h>
// jpeglib.h first: jerror.h uses its types.
#include <jerror.h>
#include <png.h>

#include <opencv2/core.hpp>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {
namespace {

void SetError(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
}

// Largest decoded image (bytes): 512 MiB, ~170 megapixels of 8-bit colour. A
// header announcing more is rejected before anything is allocated (libjpeg's
// progressive mode needs twice that again for its coefficients).
constexpr uint64_t kMaxDecodedBytes = uint64_t{512} << 20;

std::string TooLarge(uint64_t width, uint64_t height, uint64_t bytes) {
  return std::to_string(width) + " x " + std::to_string(height) + " pixels (" +
         std::to_string(bytes >> 20) + " MiB decoded) exceed the " +
         std::to_string(kMaxDecodedBytes >> 20) + " MiB limit";
}

// --- PNG (libpng's classic API; errors longjmp back to the caller) ---

struct PngReadSource {
  const unsigned char* data = nullptr;
  size_t size = 0;
  size_t offset = 0;
};

void PngReadFromMemory(png_structp png, png_bytep out, png_size_t length) {
  auto* source = static_cast<PngReadSource*>(png_get_io_ptr(png));
  if (source->offset + length > source->size) png_error(png, "truncated PNG data");
  std::memcpy(out, source->data + source->offset, length);
  source->offset += length;
}

void PngErrorHandler(png_structp png, png_const_charp message) {
  auto* text = static_cast<std::string*>(png_get_error_ptr(png));
  *text = message;
  png_longjmp(png, 1);
}

void PngWarningHandler(png_structp, png_const_charp) {}

cv::Mat DecodePng(const std::string& bytes, ImageReadMode mode, std::string* error) {
  std::string message;
  png_structp png =
      png_create_read_struct(PNG_LIBPNG_VER_STRING, &message, PngErrorHandler, PngWarningHandler);
  THROW_CHECK(png != nullptr);
  png_infop info = png_create_info_struct(png);
  THROW_CHECK(info != nullptr);
  PngReadSource source{reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), 0};
  cv::Mat image;
  std::vector<png_bytep> rows;
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    SetError(error, "invalid PNG: " + message);
    return cv::Mat();
  }
  png_set_read_fn(png, &source, PngReadFromMemory);
  png_read_info(png, info);
  const int bit_depth = png_get_bit_depth(png, info);
  const int color_type = png_get_color_type(png, info);
  // Palette -> RGB(A), grey below 8 bits -> 8, tRNS -> alpha.
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (mode == ImageReadMode::kColor) {
    if (bit_depth == 16) png_set_strip_16(png);
    png_set_strip_alpha(png);
    if (color_type == PNG_COLOR_TYPE_GRAY || color_type == PNG_COLOR_TYPE_GRAY_ALPHA) {
      png_set_gray_to_rgb(png);
    }
  } else if (bit_depth == 16) {
    png_set_swap(png);  // PNG stores 16-bit samples big-endian
  }
  png_set_bgr(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  const png_uint_32 width = png_get_image_width(png, info);
  const png_uint_32 height = png_get_image_height(png, info);
  const int channels = png_get_channels(png, info);
  const uint64_t decoded = static_cast<uint64_t>(png_get_rowbytes(png, info)) * height;
  if (decoded > kMaxDecodedBytes) {
    png_destroy_read_struct(&png, &info, nullptr);
    SetError(error, "PNG of " + TooLarge(width, height, decoded));
    return cv::Mat();
  }
  const int depth = png_get_bit_depth(png, info) == 16 ? CV_16U : CV_8U;
  image.create(static_cast<int>(height), static_cast<int>(width), CV_MAKETYPE(depth, channels));
  THROW_CHECK_EQ(png_get_rowbytes(png, info), image.step[0]);
  rows.resize(height);
  for (png_uint_32 y = 0; y < height; ++y) rows[y] = image.ptr<png_byte>(static_cast<int>(y));
  png_read_image(png, rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return image;
}

void PngWriteToString(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::string*>(png_get_io_ptr(png));
  out->append(reinterpret_cast<const char*>(data), length);
}

void PngFlush(png_structp) {}

// --- JPEG (libjpeg-turbo; errors longjmp back to the caller) ---

struct JpegError {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = {};
};

void JpegErrorExit(j_common_ptr cinfo) {
  auto* e = reinterpret_cast<JpegError*>(cinfo->err);
  cinfo->err->format_message(cinfo, e->message);
  std::longjmp(e->jump, 1);
}

// Warnings are ignored (many cameras write benign ones, e.g. extraneous bytes
// before a marker), except the end of the data before the end of the image:
// libjpeg would go on to decode the rest as grey, so that a 100-byte file
// announcing a large frame costs a full-size decode.
void JpegEmitMessage(j_common_ptr cinfo, int msg_level) {
  if (msg_level < 0 && cinfo->err->msg_code == JWRN_JPEG_EOF) cinfo->err->error_exit(cinfo);
}

cv::Mat DecodeJpeg(const std::string& bytes, ImageReadMode mode, std::string* error) {
  jpeg_decompress_struct cinfo;
  JpegError jerr;
  cinfo.err = jpeg_std_error(&jerr.manager);
  jerr.manager.error_exit = JpegErrorExit;
  jerr.manager.emit_message = JpegEmitMessage;
  cv::Mat image;
  if (setjmp(jerr.jump)) {
    jpeg_destroy_decompress(&cinfo);
    SetError(error, std::string("invalid JPEG: ") + jerr.message);
    return cv::Mat();
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo,
               reinterpret_cast<const unsigned char*>(bytes.data()),
               static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&cinfo, TRUE);
  const uint64_t decoded = uint64_t{cinfo.image_width} * cinfo.image_height * 3;
  if (decoded > kMaxDecodedBytes) {
    jpeg_destroy_decompress(&cinfo);
    SetError(error, "JPEG of " + TooLarge(cinfo.image_width, cinfo.image_height, decoded));
    return cv::Mat();
  }
  const bool grey = cinfo.num_components == 1 && mode == ImageReadMode::kUnchanged;
  // libjpeg-turbo writes BGR directly (JCS_EXT_BGR); CMYK files are not read.
  cinfo.out_color_space = grey ? JCS_GRAYSCALE : JCS_EXT_BGR;
  jpeg_start_decompress(&cinfo);
  image.create(static_cast<int>(cinfo.output_height),
               static_cast<int>(cinfo.output_width),
               grey ? CV_8UC1 : CV_8UC3);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = image.ptr<JSAMPLE>(static_cast<int>(cinfo.output_scanline));
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  return image;
}

}  // namespace

cv::Mat ReadImageFile(const std::string& path, ImageReadMode mode, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    SetError(error, "cannot open the file");
    return cv::Mat();
  }
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  static constexpr unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (bytes.size() >= 8 && std::memcmp(bytes.data(), kPngSignature, 8) == 0) {
    return DecodePng(bytes, mode, error);
  }
  if (bytes.size() >= 3 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
      static_cast<unsigned char>(bytes[1]) == 0xD8 && static_cast<unsigned char>(bytes[2]) == 0xFF) {
    return DecodeJpeg(bytes, mode, error);
  }
  SetError(error, "not a PNG or JPEG file");
  return cv::Mat();
}

std::string EncodePng(const cv::Mat& image, int compression) {
  THROW_CHECK_MSG(!image.empty(), "EncodePng: empty image");
  THROW_CHECK_MSG(image.depth() == CV_8U || image.depth() == CV_16U,
                  "EncodePng: 8 or 16-bit samples expected");
  const int channels = image.channels();
  int color_type = 0;
  switch (channels) {
    case 1: color_type = PNG_COLOR_TYPE_GRAY; break;
    case 3: color_type = PNG_COLOR_TYPE_RGB; break;
    case 4: color_type = PNG_COLOR_TYPE_RGB_ALPHA; break;
    default: THROW_CHECK_MSG(false, "EncodePng: 1, 3 or 4 channels expected, got " << channels);
  }
  THROW_CHECK_MSG(compression >= 0 && compression <= 9, "EncodePng: compression " << compression);
  std::string message;
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, &message, PngErrorHandler, PngWarningHandler);
  THROW_CHECK(png != nullptr);
  png_infop info = png_create_info_struct(png);
  THROW_CHECK(info != nullptr);
  std::string out;
  // Stored (level 0) output is the raw rows plus a filter byte per row and
  // the chunk framing; compressed output is smaller.
  out.reserve(image.total() * image.elemSize() + static_cast<size_t>(image.rows) + 1024);
  std::vector<png_bytep> rows(static_cast<size_t>(image.rows));
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    THROW_CHECK_MSG(false, "PNG encoding failed: " << message);
  }
  png_set_write_fn(png, &out, PngWriteToString, PngFlush);
  png_set_compression_level(png, compression);
  png_set_IHDR(png,
               info,
               static_cast<png_uint_32>(image.cols),
               static_cast<png_uint_32>(image.rows),
               image.depth() == CV_16U ? 16 : 8,
               color_type,
               PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (channels >= 3) png_set_bgr(png);
  if (image.depth() == CV_16U) png_set_swap(png);
  for (int y = 0; y < image.rows; ++y) {
    rows[static_cast<size_t>(y)] = const_cast<png_bytep>(image.ptr<png_byte>(y));
  }
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

bool WritePngFile(const std::string& path, const cv::Mat& image, int compression) {
  const std::string bytes = EncodePng(image, compression);
  try {
    WriteFileAtomically(path, bytes);
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

}  // namespace lisfm
