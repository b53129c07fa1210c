// The triple buffer (haptics/triple_buffer.h) between two threads: the
// reader never sees a torn value (every field of a buffer from one publish)
// and sees publishes in order, the newest one once it looks.
#include <atomic>
#include <thread>

#include <gtest/gtest.h>

#include "haptics/triple_buffer.h"

namespace incise {
namespace {

struct Big {
  long seq = 0;
  std::array<long, 512> fill{};  // written whole with seq: a torn read mixes two
};

TEST(TripleBuffer, TheReaderSeesWholeValuesInOrder) {
  auto tb = std::make_unique<TripleBuffer<Big>>();
  const long n = 200000;
  std::atomic<bool> done{false};
  std::atomic<long> seen{0};  // the reader's newest
  std::thread writer([&] {
    for (long s = 1; s <= n; ++s) {
      Big& b = tb->write_buffer();
      b.seq = s;
      b.fill.fill(s);
      tb->publish();
      // Halfway, until the reader has taken one: on a loaded machine the
      // writer could otherwise finish before the reader ran at all, and
      // the reader would see only the last publish (a test that failed by
      // scheduling, 1 run in 25 with a busy core).
      if (s == n / 2)
        while (seen.load() == 0) std::this_thread::yield();
    }
    done = true;
  });
  long last = 0, updates = 0, torn = 0, backwards = 0;
  while (!done.load() || last < n) {
    if (!tb->update()) continue;
    const Big& b = tb->read_buffer();
    ++updates;
    for (long v : b.fill) torn += v != b.seq;
    backwards += b.seq <= last;
    last = b.seq;
    seen.store(last);
  }
  writer.join();
  EXPECT_EQ(torn, 0);
  EXPECT_EQ(backwards, 0);
  EXPECT_EQ(last, n) << "the last publish is seen";
  EXPECT_GT(updates, 1) << "one before halfway, the last after it";
  EXPECT_FALSE(tb->update()) << "nothing new after the last";
}

}  // namespace
}  // namespace incise
