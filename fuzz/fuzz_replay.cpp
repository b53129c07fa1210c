// Fuzzes the replay-file reader: incise::parse_replay (engine/runtime/
// replay_file.h) on arbitrary bytes, as `incise replay F` reads them.
// parse_replay documents incise::Error as its only failure; anything else
// escaping is a bug.
//
// Every chunk carries an FNV-1a checksum, so random mutations rarely get past
// it. The first input byte picks the mode: odd = the harness first rewrites
// each chunk's checksum to match (so the fuzzer explores the chunk parsers),
// even = the bytes are parsed as they are (the checksum and framing checks).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "engine/runtime/replay_file.h"
#include "engine/util/error.h"
#include "engine/util/fnv.h"

namespace {

// Walks the chunks after the 12-byte header: u32 tag, u64 length, payload,
// u64 checksum; fixes each checksum that lies inside the bytes.
void fix_checksums(std::string& b) {
  size_t off = 12;
  while (off <= b.size() && b.size() - off >= 20) {
    std::uint64_t len = 0;
    std::memcpy(&len, b.data() + off + 4, 8);
    if (len > b.size() - off - 20) return;
    const std::uint64_t sum = incise::fnv1a(b.data() + off, 12 + len);
    std::memcpy(b.data() + off + 12 + len, &sum, 8);
    off += 20 + len;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  std::string b(reinterpret_cast<const char*>(data + 1), size - 1);
  if (data[0] & 1) fix_checksums(b);
  try {
    const incise::ReplayFile r = incise::parse_replay(b, "fuzz.replay");
    for (size_t i = 0; i < r.frames.size(); ++i)
      if (r.frames[i].frame != static_cast<int>(i) + 1 || r.frames[i].tools.size() != r.meta.compliance.size()) {
        std::fprintf(stderr, "fuzz_replay: parse_replay accepted an inconsistent frame %zu\n", i);
        std::abort();
      }
  } catch (const incise::Error&) {
    // the documented failure: a message naming the offset and frame
  }
  return 0;
}
