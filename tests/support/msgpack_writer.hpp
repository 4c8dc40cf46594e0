// A minimal MessagePack encoder for tests (https://github.com/msgpack/msgpack/blob/master/spec.md):
// written here, independently of the library's decoder, to generate stella_vslam map databases.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>

namespace lmalign::test {

class MsgpackWriter {
 public:
  const std::string& bytes() const { return out_; }

  void map_header(std::uint32_t n) { header(n, 0x80, 0xde, 0xdf); }
  void array_header(std::uint32_t n) { header(n, 0x90, 0xdc, 0xdd); }
  void str(const std::string& s) {
    if (s.size() < 32) {
      byte(static_cast<std::uint8_t>(0xa0 | s.size()));
    } else {
      byte(0xd9);
      byte(static_cast<std::uint8_t>(s.size()));  // tests use strings < 256 bytes
    }
    out_ += s;
  }
  void f64(double v) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof(bits));
    byte(0xcb);
    big_endian(bits, 8);
  }
  void integer(std::int64_t v) {
    if (v >= 0 && v < 128) {
      byte(static_cast<std::uint8_t>(v));
    } else if (v < 0 && v >= -32) {
      byte(static_cast<std::uint8_t>(0xe0 | (v + 32)));
    } else {
      byte(0xd3);
      big_endian(static_cast<std::uint64_t>(v), 8);
    }
  }

 private:
  void byte(std::uint8_t b) { out_.push_back(static_cast<char>(b)); }
  void big_endian(std::uint64_t v, int n) {
    for (int i = n - 1; i >= 0; --i) byte(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void header(std::uint32_t n, std::uint8_t fix, std::uint8_t b16, std::uint8_t b32) {
    if (n < 16) {
      byte(static_cast<std::uint8_t>(fix | n));
    } else if (n < 65536) {
      byte(b16);
      big_endian(n, 2);
    } else {
      byte(b32);
      big_endian(n, 4);
    }
  }
  std::string out_;
};

}  // namespace lmalign::test
