#pragma once
// One writer hands the latest value of T to one reader without either ever
// waiting: three buffers, one the writer fills, one the reader holds, one in
// the middle. publish() swaps the filled buffer into the middle and marks it
// fresh; update() swaps a fresh middle buffer out to the reader. Neither call
// locks or allocates, so the 1 kHz haptic tick can use it against the 30 Hz
// simulation (a seqlock would make the reader retry while the writer copies
// a 20 KB contact model).
#include <array>
#include <atomic>

namespace incise {

template <class T>
class TripleBuffer {
 public:
  // Writer: fill write_buffer(), then publish(); write_buffer() is then
  // another buffer, holding whatever it held before (fill it whole).
  T& write_buffer() { return buffers_[back_]; }
  void publish() { back_ = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel) & kIndex; }

  // Reader: true when a buffer was published since the last update();
  // read_buffer() then holds the newest one. read_buffer() is the reader's
  // own until its next update().
  // Whether update() would find a newer buffer (only the reader clears it).
  bool fresh() const { return middle_.load(std::memory_order_acquire) & kFresh; }
  bool update() {
    if (!(middle_.load(std::memory_order_acquire) & kFresh)) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndex;
    return true;
  }
  const T& read_buffer() const { return buffers_[front_]; }

 private:
  static constexpr int kIndex = 3, kFresh = 4;
  std::array<T, 3> buffers_{};
  std::atomic<int> middle_{1};  // index of the middle buffer, | kFresh when published and not yet read
  int back_ = 0;                // the writer's
  int front_ = 2;               // the reader's
};

}  // namespace incise
