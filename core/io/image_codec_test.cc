// ReadImageFile / EncodePng against OpenCV's imgcodecs (the reference the
// library code used before): the same pixels both ways, for every layout the
// project writes or reads, on synthetic images and one real JPEG.
#include "core/io/image_codec.h"

#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/errors.h"
#include "core/file_utils.h"
#include "tests/common/test_utils.h"

namespace lisfm {
namespace {

cv::Mat RandomImage(int rows, int cols, int type, uint32_t seed) {
  cv::Mat image(rows, cols, type);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, image.depth() == CV_16U ? 65536 : 256);
  return image;
}

bool SamePixels(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

std::string Describe(const cv::Mat& m) {
  return std::to_string(m.cols) + "x" + std::to_string(m.rows) + " type " +
         std::to_string(m.type());
}

TEST(ImageCodec, PngRoundTripsAndMatchesOpenCV) {
  test::TempDir dir;
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3}) {
    const cv::Mat image = RandomImage(37, 53, type, 7u + type);
    const std::string ours = dir.File("ours_" + std::to_string(type) + ".png");
    ASSERT_TRUE(WritePngFile(ours, image, 6));
    // Ours -> ours, ours -> OpenCV.
    const cv::Mat back = ReadImageFile(ours, ImageReadMode::kUnchanged);
    EXPECT_TRUE(SamePixels(back, image)) << Describe(back) << " vs " << Describe(image);
    EXPECT_TRUE(SamePixels(cv::imread(ours, cv::IMREAD_UNCHANGED), image)) << type;
    // OpenCV -> ours, in both modes.
    const std::string theirs = dir.File("theirs_" + std::to_string(type) + ".png");
    ASSERT_TRUE(cv::imwrite(theirs, image));
    EXPECT_TRUE(SamePixels(ReadImageFile(theirs, ImageReadMode::kUnchanged), image)) << type;
    const cv::Mat colour = ReadImageFile(theirs, ImageReadMode::kColor);
    EXPECT_TRUE(SamePixels(colour, cv::imread(theirs, cv::IMREAD_COLOR)))
        << type << ": " << Describe(colour);
    EXPECT_EQ(colour.type(), CV_8UC3);
  }
}

TEST(ImageCodec, JpegDecodesLikeOpenCV) {
  test::TempDir dir;
  for (const int type : {CV_8UC1, CV_8UC3}) {
    cv::Mat image = RandomImage(40, 64, type, 3u + type);
    cv::GaussianBlur(image, image, cv::Size(5, 5), 2.0);  // JPEG-like content
    const std::string path = dir.File("image_" + std::to_string(type) + ".jpg");
    ASSERT_TRUE(cv::imwrite(path, image, {cv::IMWRITE_JPEG_QUALITY, 90}));
    const cv::Mat unchanged = ReadImageFile(path, ImageReadMode::kUnchanged);
    EXPECT_TRUE(SamePixels(unchanged, cv::imread(path, cv::IMREAD_UNCHANGED))) << type;
    const cv::Mat colour = ReadImageFile(path, ImageReadMode::kColor);
    EXPECT_TRUE(SamePixels(colour, cv::imread(path, cv::IMREAD_COLOR))) << type;
  }
}

TEST(ImageCodec, RealJpegDecodesLikeOpenCV) {
  const std::string path =
      test::SharedData("sfm_strecha/Herz-Jesus-P8/images_half/0000.jpg");
  if (!FileExists(path)) GTEST_SKIP() << "real data missing: " << path;
  const cv::Mat ours = ReadImageFile(path, ImageReadMode::kColor);
  ASSERT_FALSE(ours.empty());
  EXPECT_TRUE(SamePixels(ours, cv::imread(path, cv::IMREAD_COLOR))) << Describe(ours);
}

TEST(ImageCodec, BadFilesGiveAnEmptyImageAndTheReason) {
  test::TempDir dir;
  std::string why;
  EXPECT_TRUE(ReadImageFile(dir.File("missing.png"), ImageReadMode::kColor, &why).empty());
  EXPECT_EQ(why, "cannot open the file");
  {
    std::ofstream(dir.File("text.png")) << "not an image\n";
  }
  EXPECT_TRUE(ReadImageFile(dir.File("text.png"), ImageReadMode::kColor, &why).empty());
  EXPECT_EQ(why, "not a PNG or JPEG file");
  // A PNG and a JPEG cut in half.
  const cv::Mat image = RandomImage(64, 64, CV_8UC3, 1);
  const std::string png = EncodePng(image);
  {
    std::ofstream(dir.File("cut.png"), std::ios::binary) << png.substr(0, png.size() / 2);
  }
  EXPECT_TRUE(ReadImageFile(dir.File("cut.png"), ImageReadMode::kUnchanged, &why).empty());
  EXPECT_NE(why.find("invalid PNG"), std::string::npos) << why;
  std::vector<uchar> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", image, jpeg));
  {
    std::ofstream(dir.File("cut.jpg"), std::ios::binary)
        .write(reinterpret_cast<const char*>(jpeg.data()), static_cast<std::streamsize>(20));
  }
  EXPECT_TRUE(ReadImageFile(dir.File("cut.jpg"), ImageReadMode::kColor, &why).empty());
  EXPECT_NE(why.find("invalid JPEG"), std::string::npos) << why;
  // Data ending before the image does: an error, not a grey-filled decode.
  {
    std::ofstream(dir.File("short.jpg"), std::ios::binary)
        .write(reinterpret_cast<const char*>(jpeg.data()), static_cast<std::streamsize>(jpeg.size() / 2));
  }
  EXPECT_TRUE(ReadImageFile(dir.File("short.jpg"), ImageReadMode::kColor, &why).empty());
  EXPECT_NE(why.find("invalid JPEG: Premature end of JPEG file"), std::string::npos) << why;
  // Headers announcing more than 512 MiB of pixels are refused before decoding:
  // a JPEG whose frame header says 60000 x 60000 (the seed's SOF0 size fields).
  std::string big(reinterpret_cast<const char*>(jpeg.data()), jpeg.size());
  const size_t sof = big.find("\xFF\xC0");
  ASSERT_NE(sof, std::string::npos);
  for (const size_t at : {sof + 5, sof + 7}) {  // height, width: big endian
    big[at] = static_cast<char>(0xEA);
    big[at + 1] = static_cast<char>(0x60);
  }
  {
    std::ofstream(dir.File("huge.jpg"), std::ios::binary) << big;
  }
  EXPECT_TRUE(ReadImageFile(dir.File("huge.jpg"), ImageReadMode::kColor, &why).empty());
  EXPECT_NE(why.find("60000 x 60000 pixels"), std::string::npos) << why;
  // Unsupported layouts are programming errors.
  EXPECT_THROW(EncodePng(cv::Mat(4, 4, CV_32FC1)), InternalError);
  EXPECT_THROW(EncodePng(cv::Mat(4, 4, CV_8UC2)), InternalError);
}

}  // namespace
}  // namespace lisfm
