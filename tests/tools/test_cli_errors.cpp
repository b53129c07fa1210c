// Issue 24, as a careless user or an attacker runs the command line: deep
// JSON, absurd or non-finite options, outputs that cannot be written or come
// from a failed run, numerical failures; each must end in a clear error and
// leave nothing half-written.
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/tools/cli_test_util.h"
#include "tests/tools/temp_dir_test.h"

namespace fs = std::filesystem;

namespace {

using incise::test::incise;
using incise::test::Result;

class CliErrors : public incise::test::TempDirTest {
 protected:
  // A corotated tet4 cantilever (L = 4, 1 x 1) fixed at x = 0, under gravity.
  void beam_scene(const std::string& material = R"("young": 1e5, "poisson": 0.3, "density": 1)",
                  const std::string& extra = "") const {
    ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 4 2 2 --out " + path("beam.vtu")).code, 0);
    write("scene.json", R"({"mesh": {"file": "beam.vtu", "order": 1},
      "material": {"model": "corotated", )" + material + R"(},
      "gravity": [0, 0, -1], "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}])" + extra + "}");
  }
  // Every file below the test's folder whose name contains `part`.
  std::vector<std::string> files_with(const std::string& part) const {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir_))
      if (e.path().filename().string().find(part) != std::string::npos) out.push_back(e.path().string());
    return out;
  }
};

// A scene nested 100,000 arrays deep overflowed the stack while the error was
// formatted; now it is refused before it is parsed.
TEST_F(CliErrors, DeeplyNestedSceneIsAnError) {
  const int n = 100000;
  write("deep.json", std::string(n, '[') + std::string(n, ']'));
  const Result r = incise("run " + path("deep.json") + " --frames 1");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(path("deep.json") + ":1: nested deeper than 64 levels of [ and {"), std::string::npos) << r.out;
  // the same through --set (one argument holds at most 128 KiB: 60,000 levels)
  beam_scene();
  const Result s = incise("run " + path("scene.json") + " --frames 1 --set 'material.young=" +
                          std::string(60000, '[') + std::string(60000, ']') + "'");
  EXPECT_EQ(s.code, 1) << s.out.substr(0, 400);
  EXPECT_NE(s.out.find("(120015 characters): the value is nested deeper than 64 levels of [ and {"), std::string::npos)
      << s.out.substr(0, 400);
}

// An output path that is a folder: a clear error, and no temporary file left
// beside it (bench --json, --trace; static --out).
TEST_F(CliErrors, OutputPathThatIsAFolderLeavesNoTemporaryFile) {
  beam_scene();
  fs::create_directories(path("taken"));
  write("p.csv", "1,0.5,0.5\n");
  for (const std::string& args : {"bench " + path("scene.json") + " --frames 2 --json " + path("taken"),
                                  "bench " + path("scene.json") + " --frames 2 --trace " + path("taken"),
                                  "static " + path("scene.json") + " --probe " + path("p.csv") + " --out " + path("taken")}) {
    const Result r = incise(args);
    EXPECT_EQ(r.code, 1) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(path("taken") + ": cannot write: it is a directory"), std::string::npos) << args << "\n" << r.out;
    EXPECT_TRUE(files_with(".tmp").empty()) << args << ": " << files_with(".tmp").front();
  }
}

}  // namespace
