// The optional MP4: ffmpeg is looked up on PATH at run time and never required.
#include "render/video.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "render_test_util.h"

namespace incise::test {
namespace {

namespace fs = std::filesystem;

// Sets PATH for one test and restores it.
struct ScopedPath {
  std::string old;
  explicit ScopedPath(const std::string& p) : old(std::getenv("PATH") ? std::getenv("PATH") : "") {
    setenv("PATH", p.c_str(), 1);
  }
  ~ScopedPath() { setenv("PATH", old.c_str(), 1); }
};

TEST(Video, NoFfmpegMeansNoVideoAndNoError) {
  const fs::path empty = fs::path(output_dir()) / "video_empty_bin";
  fs::create_directories(empty);
  ScopedPath p(empty.string());
  EXPECT_EQ(find_ffmpeg(), "");
  EXPECT_EQ(encode_mp4(output_dir(), 30.0), "");
}

TEST(Video, FfmpegOnPathIsCalledWithTheFramePattern) {
  // A stand-in ffmpeg that records its arguments and creates the output file.
  const fs::path bin = fs::path(output_dir()) / "video_fake_bin";
  const fs::path frames = fs::path(output_dir()) / "video frames";  // a space: arguments must be quoted
  fs::create_directories(bin);
  fs::create_directories(frames);
  const fs::path log = bin / "args.txt";
  {
    std::ofstream sh(bin / "ffmpeg");
    sh << "#!/bin/sh\nfor a in \"$@\"; do echo \"$a\"; done > '" << log.string() << "'\n"
       << "for a in \"$@\"; do last=\"$a\"; done\ntouch \"$last\"\n";
  }
  fs::permissions(bin / "ffmpeg", fs::perms::owner_all);
  ScopedPath p(bin.string() + ":/usr/bin:/bin");
  EXPECT_EQ(find_ffmpeg(), (bin / "ffmpeg").string());
  const std::string video = encode_mp4(frames.string(), 30.0);
  EXPECT_EQ(video, (frames / "frames.mp4").string());
  EXPECT_TRUE(fs::exists(video));
  std::ifstream in(log);
  std::stringstream args;
  args << in.rdbuf();
  EXPECT_NE(args.str().find("\n" + (frames / "frame_%05d.png").string() + "\n"), std::string::npos) << args.str();
  EXPECT_NE(args.str().find("\nyuv420p\n"), std::string::npos) << args.str();
}

}  // namespace
}  // namespace incise::test
