#include "banmo/io/npy.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>

#include "banmo/util/error.h"

namespace banmo {
namespace {

// The v1.0 layout of the NumPy format specification for
// np.arange(6, dtype='<f2').reshape(2, 3): magic, version, little-endian
// header length, the dict padded with spaces so that the data start at a
// multiple of 64 bytes (here 128), a newline, then the 6 half floats (0..5).
constexpr std::size_t kDataOffset = 128;
std::string ReferenceNpy() {
  std::string dict = "{'descr': '<f2', 'fortran_order': False, 'shape': (2, 3), }";
  dict.append(kDataOffset - 10 - dict.size() - 1, ' ');
  dict += '\n';
  std::string bytes("\x93NUMPY\x01\x00", 8);
  bytes += static_cast<char>(dict.size());
  bytes += '\0';
  bytes += dict;
  const unsigned char halves[12] = {0x00, 0x00, 0x00, 0x3c, 0x00, 0x40,
                                    0x00, 0x42, 0x00, 0x44, 0x00, 0x45};
  bytes.append(reinterpret_cast<const char*>(halves), sizeof(halves));
  return bytes;
}

// Replaces the header dict of ReferenceNpy() with `dict` (re-padded) and
// keeps the 12 data bytes.
std::string WithDict(std::string dict) {
  const std::string ref = ReferenceNpy();
  dict.append(kDataOffset - 10 - dict.size() - 1, ' ');
  dict += '\n';
  std::string bytes("\x93NUMPY\x01\x00", 8);
  bytes += static_cast<char>(dict.size());
  bytes += '\0';
  return bytes + dict + ref.substr(kDataOffset);
}

void ExpectRejected(const std::string& bytes, const std::string& fragment) {
  try {
    DecodeNpy(bytes, "test.npy");
    FAIL() << "accepted bad .npy, expected an error mentioning '" << fragment << "'";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("test.npy"), std::string::npos) << msg;
    EXPECT_NE(msg.find(fragment), std::string::npos) << msg;
  }
}

TEST(Npy, DecodesSpecLayout) {
  const cv::Mat m = DecodeNpy(ReferenceNpy(), "test.npy");
  ASSERT_EQ(m.type(), CV_16FC1);
  ASSERT_EQ(m.rows, 2);
  ASSERT_EQ(m.cols, 3);
  cv::Mat f;
  m.convertTo(f, CV_32F);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(f.at<float>(i / 3, i % 3), static_cast<float>(i));
}

// Found by fuzz/fuzz_npy.cc: an empty array (a 0 in its shape) has no data
// pointer, and copying its 0 bytes from there was undefined behaviour.
TEST(Npy, EmptyArrayDecodesToAnEmptyMatrix) {
  const std::string ref = WithDict("{'descr': '<f2', 'fortran_order': False, 'shape': (0, 3), }");
  const std::string bytes = ref.substr(0, kDataOffset);  // no data bytes
  const cv::Mat m = DecodeNpy(bytes, "test.npy");
  EXPECT_TRUE(m.empty());
}

TEST(Npy, EncodeMatchesSpecLayout) {
  cv::Mat f(2, 3, CV_32F);
  for (int i = 0; i < 6; ++i) f.at<float>(i / 3, i % 3) = static_cast<float>(i);
  cv::Mat h;
  f.convertTo(h, CV_16F);
  EXPECT_EQ(EncodeNpy(h, /*channel_axis=*/false), ReferenceNpy());
}

TEST(Npy, RoundTripTypes) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uni(-100.f, 100.f);
  for (int type : {CV_16FC(16), CV_32FC1, CV_32FC3, CV_8UC1, CV_16UC1, CV_64FC2}) {
    cv::Mat m(7, 5, type);
    cv::randu(m, 0, 200);
    const std::string bytes = EncodeNpy(m);
    EXPECT_EQ((bytes.size() - m.total() * m.elemSize()) % 64, 0u);  // aligned data
    const cv::Mat back = DecodeNpy(bytes, "x.npy");
    ASSERT_EQ(back.type(), m.type());
    ASSERT_EQ(back.size(), m.size());
    EXPECT_EQ(0, std::memcmp(back.data, m.data, m.total() * m.elemSize()));
    const NpyHeader h = ParseNpyHeader(bytes, "x.npy");
    EXPECT_EQ(h.shape, (std::vector<std::int64_t>{7, 5, m.channels()}));
  }
}

TEST(Npy, RejectsBadMagic) {
  std::string b = ReferenceNpy();
  b[1] = 'X';
  ExpectRejected(b, "magic");
  ExpectRejected("", "magic");
}

TEST(Npy, RejectsUnsupportedVersion) {
  std::string b = ReferenceNpy();
  b[6] = 3;
  ExpectRejected(b, "version 3.0");
}

TEST(Npy, RejectsTruncatedHeader) { ExpectRejected(ReferenceNpy().substr(0, 40), "truncated"); }

TEST(Npy, RejectsTruncatedAndTrailingData) {
  const std::string b = ReferenceNpy();
  ExpectRejected(b.substr(0, b.size() - 1), "truncated");
  ExpectRejected(b + "x", "trailing bytes");
}

TEST(Npy, RejectsBadDicts) {
  ExpectRejected(WithDict("{'descr': '>f2', 'fortran_order': False, 'shape': (2, 3), }"),
                 "big-endian");
  ExpectRejected(WithDict("{'descr': '<i8', 'fortran_order': False, 'shape': (2, 3), }"),
                 "unsupported dtype '<i8'");
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': True, 'shape': (3, 2), }"),
                 "fortran_order");
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': False, }"), "missing key 'shape'");
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': False, 'shape': (2, 3), 'x': 1}"),
                 "unknown key 'x'");
  ExpectRejected(WithDict("{'descr': '<f2', 'descr': '<f2', 'shape': (2, 3), }"),
                 "duplicate key 'descr'");
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': False, 'shape': (-2, 3), }"),
                 "non-negative integer");
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': False, 'shape': (2, 3) "), "expected");
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': Maybe, 'shape': (2, 3), }"),
                 "True or False");
  // Shape with a different element count than the data: size mismatch.
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': False, 'shape': (2, 4), }"),
                 "truncated");
  // 1-D and 4-D arrays are not images.
  ExpectRejected(WithDict("{'descr': '<f2', 'fortran_order': False, 'shape': (6,), }"),
                 "2-D (H, W) or 3-D");
}

TEST(Npy, RejectsHeaderWithoutNewline) {
  std::string b = ReferenceNpy();
  b[kDataOffset - 1] = ' ';
  ExpectRejected(b, "newline");
}

}  // namespace
}  // namespace banmo
