// vision/templates load_template_database() on a .tdb file (docs/template-database.md). The
// header's payload size and CRC-32 are set to match the input's payload first, so mutations
// reach the payload parser instead of stopping at the checksum; magic, version and header size
// are left as the input has them. A version-5 file that loads is saved again and must come out
// byte for byte the same but for the reserved word (the format has one encoding of each
// database).

#include "vision/templates/template_database.hpp"
#include "fuzz/fuzz_support.hpp"

#include <zlib.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

namespace {

constexpr size_t kHeaderBytes = 32;  // magic 8, version 4, header size 4, payload size 8, CRC-32 4, 0 4

template <class T>
void put_at(std::vector<uint8_t>& bytes, size_t at, T v) {
  std::memcpy(bytes.data() + at, &v, sizeof v);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  if (bytes.size() >= kHeaderBytes) {
    const size_t payload = bytes.size() - kHeaderBytes;
    put_at<uint64_t>(bytes, 16, payload);
    put_at<uint32_t>(
        bytes, 24,
        static_cast<uint32_t>(crc32(crc32(0L, Z_NULL, 0), bytes.data() + kHeaderBytes, static_cast<uInt>(payload))));
  }
  const auto input = mfcd::fuzz::scratch_dir() / "input.tdb";
  mfcd::fuzz::write_file(input, bytes.data(), bytes.size());
  mfcd::vision::TemplateDatabase db;
  try {
    db = mfcd::vision::load_template_database(input);
  } catch (const mfcd::vision::TemplateFileError&) {
    return 0;  // documented: the file and the reason named
  }
  uint32_t version = 0;
  std::memcpy(&version, bytes.data() + 8, sizeof version);
  if (version != mfcd::vision::TemplateDatabase::kVersion) return 0;
  const auto again = mfcd::fuzz::scratch_dir() / "again.tdb";
  mfcd::vision::save_template_database(db, again);
  std::ifstream in(again, std::ios::binary);
  const std::vector<uint8_t> saved((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Bytes 28..31 are reserved: written as 0, not read.
  if (saved.size() != bytes.size() || std::memcmp(saved.data(), bytes.data(), 28) != 0 ||
      std::memcmp(saved.data() + kHeaderBytes, bytes.data() + kHeaderBytes, bytes.size() - kHeaderBytes) != 0)
    mfcd::fuzz::finding("a loaded version-5 database saves to other bytes");
  return 0;
}
