#include "banmo/io/npy.h"

#include <cctype>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>

#include "banmo/io/codecs.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr std::size_t kMagicSize = 6;

struct DtypeInfo {
  const char* descr;
  int cv_depth;
  int item_size;
};
constexpr DtypeInfo kDtypes[] = {{"|u1", CV_8U, 1},
                                 {"<u2", CV_16U, 2},
                                 {"<f2", CV_16F, 2},
                                 {"<f4", CV_32F, 4},
                                 {"<f8", CV_64F, 8}};

const DtypeInfo* FindDtype(const std::string& descr) {
  for (const DtypeInfo& d : kDtypes) {
    if (descr == d.descr) return &d;
  }
  return nullptr;
}

const DtypeInfo* FindDtypeForDepth(int depth) {
  for (const DtypeInfo& d : kDtypes) {
    if (depth == d.cv_depth) return &d;
  }
  return nullptr;
}

bool HostIsLittleEndian() {
  const std::uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// Parser of the header's Python dict literal, e.g.
//   {'descr': '<f2', 'fortran_order': False, 'shape': (512, 512, 16), }
class HeaderParser {
 public:
  HeaderParser(const std::string& text, const std::string& name) : s_(text), name_(name) {}

  NpyHeader Parse() {
    NpyHeader header;
    std::map<std::string, bool> seen;
    SkipSpaces();
    Expect('{');
    while (true) {
      SkipSpaces();
      if (Peek() == '}') {
        ++pos_;
        break;
      }
      const std::string key = ParseString();
      SkipSpaces();
      Expect(':');
      SkipSpaces();
      if (seen[key]) Fail("duplicate key '" + key + "'");
      seen[key] = true;
      if (key == "descr") {
        header.descr = ParseString();
      } else if (key == "fortran_order") {
        header.fortran_order = ParseBool();
      } else if (key == "shape") {
        header.shape = ParseShape();
      } else {
        Fail("unknown key '" + key + "' (expected 'descr', 'fortran_order', 'shape')");
      }
      SkipSpaces();
      if (Peek() == ',') {
        ++pos_;
      } else if (Peek() != '}') {
        Fail("expected ',' or '}'");
      }
    }
    // Padding: spaces, then exactly one final newline.
    while (pos_ < s_.size() && s_[pos_] == ' ') ++pos_;
    if (pos_ + 1 != s_.size() || s_[pos_] != '\n') {
      Fail("header must end with spaces and one newline after the dict");
    }
    for (const char* key : {"descr", "fortran_order", "shape"}) {
      if (!seen[key]) Fail(std::string("missing key '") + key + "'");
    }
    return header;
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    ThrowInputError(name_, ": bad .npy header (", what, " at character ", pos_, ")");
  }
  char Peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void SkipSpaces() {
    while (pos_ < s_.size() && s_[pos_] == ' ') ++pos_;
  }
  void Expect(char c) {
    if (Peek() != c) Fail(std::string("expected '") + c + "'");
    ++pos_;
  }
  std::string ParseString() {
    const char quote = Peek();
    if (quote != '\'' && quote != '"') Fail("expected a quoted string");
    ++pos_;
    const std::size_t end = s_.find(quote, pos_);
    if (end == std::string::npos) Fail("unterminated string");
    std::string out = s_.substr(pos_, end - pos_);
    pos_ = end + 1;
    return out;
  }
  bool ParseBool() {
    if (s_.compare(pos_, 4, "True") == 0) {
      pos_ += 4;
      return true;
    }
    if (s_.compare(pos_, 5, "False") == 0) {
      pos_ += 5;
      return false;
    }
    Fail("expected True or False");
  }
  std::vector<std::int64_t> ParseShape() {
    std::vector<std::int64_t> shape;
    Expect('(');
    while (true) {
      SkipSpaces();
      if (Peek() == ')') {
        ++pos_;
        break;
      }
      if (!std::isdigit(static_cast<unsigned char>(Peek()))) {
        Fail("expected a non-negative integer dimension");
      }
      std::int64_t value = 0;
      while (std::isdigit(static_cast<unsigned char>(Peek()))) {
        if (value > (std::numeric_limits<std::int64_t>::max() - 9) / 10)
          Fail("dimension too large");
        value = value * 10 + (s_[pos_] - '0');
        ++pos_;
      }
      // Python writes 512L on some old versions.
      if (Peek() == 'L') ++pos_;
      shape.push_back(value);
      SkipSpaces();
      if (Peek() == ',') {
        ++pos_;
      } else if (Peek() != ')') {
        Fail("expected ',' or ')' in shape");
      }
    }
    return shape;
  }

  const std::string& s_;
  const std::string& name_;
  std::size_t pos_ = 0;
};

}  // namespace

int NpyHeader::ItemSize() const {
  const DtypeInfo* d = FindDtype(descr);
  return d ? d->item_size : 0;
}

std::size_t NpyHeader::DataBytes() const {
  std::size_t n = static_cast<std::size_t>(ItemSize());
  for (std::int64_t dim : shape) n *= static_cast<std::size_t>(dim);
  return n;
}

NpyHeader ParseNpyHeader(const std::string& bytes, const std::string& name) {
  if (bytes.size() < kMagicSize + 4 || std::memcmp(bytes.data(), kMagic, kMagicSize) != 0) {
    ThrowInputError(name, ": not a NumPy .npy file (expected the magic string \\x93NUMPY)");
  }
  const int major = static_cast<unsigned char>(bytes[6]);
  const int minor = static_cast<unsigned char>(bytes[7]);
  if (!((major == 1 || major == 2) && minor == 0)) {
    ThrowInputError(name, ": unsupported .npy format version ", major, ".", minor,
                    " (expected 1.0 or 2.0)");
  }
  std::size_t header_len = 0;
  std::size_t prefix = 0;
  const auto* u = reinterpret_cast<const unsigned char*>(bytes.data());
  if (major == 1) {
    header_len = u[8] | (static_cast<std::size_t>(u[9]) << 8);
    prefix = 10;
  } else {
    if (bytes.size() < 12) ThrowInputError(name, ": truncated .npy header");
    header_len = u[8] | (static_cast<std::size_t>(u[9]) << 8) |
                 (static_cast<std::size_t>(u[10]) << 16) | (static_cast<std::size_t>(u[11]) << 24);
    prefix = 12;
  }
  if (prefix + header_len > bytes.size()) {
    ThrowInputError(name, ": truncated .npy header (header length ", header_len, ", file has ",
                    bytes.size() - prefix, " bytes after the prefix)");
  }
  const std::string text = bytes.substr(prefix, header_len);
  NpyHeader header = HeaderParser(text, name).Parse();
  header.major_version = major;
  header.data_offset = prefix + header_len;
  if (header.descr.size() == 3 && header.descr[0] == '>') {
    ThrowInputError(name, ": big-endian dtype '", header.descr,
                    "' is not supported (expected little endian, e.g. '<f2')");
  }
  if (FindDtype(header.descr) == nullptr) {
    ThrowInputError(name, ": unsupported dtype '", header.descr,
                    "' (expected one of |u1 <u2 <f2 <f4 <f8)");
  }
  if (header.fortran_order) {
    ThrowInputError(name, ": fortran_order True is not supported (expected C order)");
  }
  // Overflow check of the element count (each dimension fits in int64).
  std::size_t n = static_cast<std::size_t>(header.ItemSize());
  for (std::int64_t dim : header.shape) {
    if (dim != 0 && n > std::numeric_limits<std::size_t>::max() / static_cast<std::size_t>(dim)) {
      ThrowInputError(name, ": array shape too large");
    }
    n *= static_cast<std::size_t>(dim);
  }
  return header;
}

NpyHeader ReadNpyHeader(const std::string& path) {
  CheckRegularFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) ThrowInputError(path, ": cannot open file");
  in.seekg(0, std::ios::end);
  const std::size_t file_size = static_cast<std::size_t>(in.tellg());
  in.seekg(0);
  // The header is short; 64 KiB covers any sane header (v1.0 allows 65535 bytes + 10).
  std::string head(std::min<std::size_t>(file_size, 65536 + 12), '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  const NpyHeader header = ParseNpyHeader(head, path);
  const std::size_t expected = header.data_offset + header.DataBytes();
  if (file_size != expected) {
    ThrowInputError(path, ": .npy file has ", file_size, " bytes, expected ", expected,
                    file_size < expected ? " (truncated)" : " (trailing bytes)");
  }
  return header;
}

std::string EncodeNpy(const cv::Mat& image, bool channel_axis) {
  CHECK(HostIsLittleEndian()) << "the .npy writer assumes a little-endian host";
  const DtypeInfo* d = FindDtypeForDepth(image.depth());
  CHECK(d != nullptr) << "EncodeNpy: unsupported cv::Mat depth " << image.depth();
  CHECK_EQ(image.dims, 2);
  const cv::Mat data = image.isContinuous() ? image : image.clone();
  std::string dict = std::string("{'descr': '") + d->descr +
                     "', 'fortran_order': False, 'shape': (" + std::to_string(image.rows) + ", " +
                     std::to_string(image.cols);
  if (channel_axis || image.channels() > 1) dict += ", " + std::to_string(image.channels());
  dict += "), }";
  // Pad with spaces so that the data start is 64-byte aligned (as NumPy does).
  std::size_t total = 10 + dict.size() + 1;
  const std::size_t padded = (total + 63) / 64 * 64;
  dict.append(padded - total, ' ');
  dict += '\n';
  CHECK_LE(dict.size(), 65535u);
  std::string out(kMagic, kMagicSize);
  out += static_cast<char>(1);
  out += static_cast<char>(0);
  out += static_cast<char>(dict.size() & 0xff);
  out += static_cast<char>((dict.size() >> 8) & 0xff);
  out += dict;
  const std::size_t bytes = data.total() * data.elemSize();
  out.append(reinterpret_cast<const char*>(data.data), bytes);
  return out;
}

cv::Mat DecodeNpy(const std::string& bytes, const std::string& name) {
  CHECK(HostIsLittleEndian()) << "the .npy reader assumes a little-endian host";
  const NpyHeader header = ParseNpyHeader(bytes, name);
  const std::size_t expected = header.data_offset + header.DataBytes();
  if (bytes.size() != expected) {
    ThrowInputError(name, ": .npy file has ", bytes.size(), " bytes, expected ", expected,
                    bytes.size() < expected ? " (truncated)" : " (trailing bytes)");
  }
  if (header.shape.size() != 2 && header.shape.size() != 3) {
    ThrowInputError(name, ": expected a 2-D (H, W) or 3-D (H, W, C) array, found ",
                    header.shape.size(), " dimensions");
  }
  const std::int64_t rows = header.shape[0];
  const std::int64_t cols = header.shape[1];
  const std::int64_t channels = header.shape.size() == 3 ? header.shape[2] : 1;
  if (rows > std::numeric_limits<int>::max() || cols > std::numeric_limits<int>::max() ||
      channels < 1 || channels > CV_CN_MAX) {
    ThrowInputError(name,
                    ": unsupported array shape (rows, cols < 2^31 and 1 <= channels <= ", CV_CN_MAX,
                    " expected)");
  }
  const DtypeInfo* d = FindDtype(header.descr);
  cv::Mat image(static_cast<int>(rows), static_cast<int>(cols),
                CV_MAKETYPE(d->cv_depth, static_cast<int>(channels)));
  // An empty array (a 0 in the shape) has no data pointer: nothing to copy
  // (memcpy from/to null is undefined even for 0 bytes; found by fuzz_npy).
  if (header.DataBytes() > 0) {
    std::memcpy(image.data, bytes.data() + header.data_offset, header.DataBytes());
  }
  return image;
}

cv::Mat ReadNpy(const std::string& path) { return DecodeNpy(ReadFileBytes(path), path); }

void WriteNpy(const std::string& path, const cv::Mat& image, bool channel_axis) {
  WriteFileAtomic(path, EncodeNpy(image, channel_axis));
}

}  // namespace banmo
