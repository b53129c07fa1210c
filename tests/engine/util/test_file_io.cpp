// engine/util/file_io.h: inputs are read only from regular files within a
// size limit (a FIFO would block, /dev/zero would fill memory); outputs are
// atomic and leave nothing behind on failure.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <fstream>
#include <string>
#include <sys/stat.h>
#include <unistd.h>

#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "tests/engine/error_of.h"

namespace incise {
namespace {

namespace fs = std::filesystem;

using test::error_of;

struct FileIo : ::testing::Test {
  fs::path dir = fs::temp_directory_path() / ("incise_file_io_" + std::to_string(::getpid()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(FileIo, ReadsARegularFileWhole) {
  const std::string p = (dir / "a.txt").string();
  std::ofstream(p) << "abc\n";
  EXPECT_EQ(read_input_file(p, 100, "scene file"), "abc\n");
}

TEST_F(FileIo, DropsALeadingUtf8ByteOrderMarkOnly) {
  const fs::path p = dir / "bom.csv";
  std::ofstream(p, std::ios::binary) << "\xEF\xBB\xBFt,x\n0,\xEF\xBB\xBF";
  EXPECT_EQ(read_input_file(p.string(), 1024, "trajectory"), "t,x\n0,\xEF\xBB\xBF");
}

TEST_F(FileIo, RefusesAFifoWithoutBlocking) {
  const std::string p = (dir / "pipe").string();
  ASSERT_EQ(::mkfifo(p.c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { read_input_file(p, 100, "mesh file"); }),
            p + ": cannot read mesh file: it is a FIFO, not a regular file");
}

TEST_F(FileIo, RefusesADeviceAndADirectory) {
  EXPECT_EQ(error_of([&] { read_input_file("/dev/zero", 100, "probe file"); }),
            "/dev/zero: cannot read probe file: it is a character device, not a regular file");
  EXPECT_EQ(error_of([&] { read_input_file(dir.string(), 100, "scene file"); }),
            dir.string() + ": cannot read scene file: it is a directory, not a regular file");
}

TEST_F(FileIo, RefusesAFileOverTheLimitBeforeReadingIt) {
  const std::string p = (dir / "big.csv").string();
  std::ofstream(p) << std::string(3 << 20, 'x');
  EXPECT_EQ(error_of([&] { read_input_file(p, 1 << 20, "trajectory file"); }),
            p + ": trajectory file is 3 MiB, more than the limit of 1 MiB for such files");
  EXPECT_EQ(error_of([&] { check_input_file(p, 1 << 20, "trajectory file"); }),
            p + ": trajectory file is 3 MiB, more than the limit of 1 MiB for such files");
}

TEST_F(FileIo, AtomicWriteToAFolderLeavesNoTemporaryFile) {
  const fs::path out = dir / "out";
  fs::create_directories(out);
  EXPECT_EQ(error_of([&] { write_file_atomic(out.string(), "x"); }), out.string() + ": cannot write: it is a directory");
  int left = 0;
  for (const auto& e : fs::directory_iterator(dir)) left += e.path() != out;
  EXPECT_EQ(left, 0);
  const std::string p = (dir / "r.json").string();
  write_file_atomic(p, "{}\n");
  EXPECT_EQ(read_input_file(p, 100, "scene file"), "{}\n");
}

}  // namespace
}  // namespace incise
