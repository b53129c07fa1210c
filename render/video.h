#pragma once
// Optional MP4 from a folder of frame_%05d.png, when an ffmpeg executable is
// on PATH (found at run time; never a build or test dependency).
#include <string>

namespace incise {

// Full path of ffmpeg on PATH, or "" when there is none.
std::string find_ffmpeg();
// Encodes DIR/frame_%05d.png at fps into DIR/frames.mp4 (H.264, yuv420p).
// Returns the video's path, or "" when ffmpeg is absent. Throws incise::Error
// when ffmpeg is present but fails.
std::string encode_mp4(const std::string& dir, double fps);

}  // namespace incise
