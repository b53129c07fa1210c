#include "engine/solve/block_recycler.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <utility>
#include <vector>

#include <suitesparse/SuiteSparse_config.h>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define INCISE_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define INCISE_ASAN 1
#endif

namespace incise {

namespace {

constexpr size_t kMinBlock = size_t{1} << 20;    // smaller requests go straight to malloc
constexpr size_t kMaxKept = 16;                  // blocks kept at most
constexpr size_t kMaxBytes = size_t{256} << 20;  // bytes kept at most
constexpr size_t kMagic = 0x696e63697365b10cULL;

// Every block carries this header (16 bytes: the user pointer keeps malloc's
// 16-byte alignment), so free and realloc know its capacity.
struct Header {
  size_t capacity;  // usable bytes after the header
  size_t magic;
};
static_assert(sizeof(Header) == 16, "header keeps 16-byte alignment");

struct Pool {
  std::mutex mutex;
  std::vector<std::pair<size_t, Header*>> kept;  // (capacity, block)
  size_t kept_bytes = 0;
  std::atomic<long> reused{0}, grown{0}, fresh{0};
};

Pool& pool() {
  static Pool* p = new Pool;  // never destroyed: CHOLMOD may free during static destruction
  return *p;
}

void* user(Header* h) { return reinterpret_cast<char*>(h) + sizeof(Header); }
Header* header(void* p) { return reinterpret_cast<Header*>(static_cast<char*>(p) - sizeof(Header)); }

Header* fresh_block(size_t capacity) {
  if (capacity > SIZE_MAX - sizeof(Header)) return nullptr;
  auto* h = static_cast<Header*>(std::malloc(sizeof(Header) + capacity));
  if (!h) return nullptr;
  h->capacity = capacity;
  h->magic = kMagic;
  return h;
}

}  // namespace

namespace recycler {

void* allocate(size_t size) {
  if (size == 0) size = 1;
  if (size < kMinBlock) {
    Header* h = fresh_block(size);
    return h ? user(h) : nullptr;
  }
  Pool& p = pool();
  // 1/8 headroom on new and grown blocks: the next factor of a growing incision pattern still fits.
  const size_t capacity = size + size / 8;
  Header* grow = nullptr;
  {
    // The smallest kept block that fits and wastes at most half of itself;
    // failing that, the largest one of at least half the size, grown.
    std::lock_guard<std::mutex> lock(p.mutex);
    size_t best = p.kept.size(), largest = p.kept.size();
    for (size_t k = 0; k < p.kept.size(); ++k) {
      const size_t cap = p.kept[k].first;
      if (cap >= size && cap / 2 <= size && (best == p.kept.size() || cap < p.kept[best].first)) best = k;
      if (cap < size && cap >= size / 2 && (largest == p.kept.size() || cap > p.kept[largest].first)) largest = k;
    }
    const size_t take = best < p.kept.size() ? best : largest;
    if (take < p.kept.size()) {
      Header* h = p.kept[take].second;
      p.kept_bytes -= p.kept[take].first;
      p.kept.erase(p.kept.begin() + static_cast<std::ptrdiff_t>(take));
      if (take == best) {
        p.reused.fetch_add(1, std::memory_order_relaxed);
        return user(h);
      }
      grow = h;
    }
  }
  if (grow) {
    // realloc keeps the pages already touched where it can: a mapped block
    // (above glibc's mmap threshold) moves by mremap, a heap block grows in
    // place when the space after it is free, and is copied otherwise.
    if (auto* h = static_cast<Header*>(std::realloc(grow, sizeof(Header) + capacity))) {
      h->capacity = capacity;
      p.grown.fetch_add(1, std::memory_order_relaxed);
      return user(h);
    }
    std::free(grow);
  }
  Header* h = fresh_block(capacity);
  if (!h) h = fresh_block(size);
  if (!h) return nullptr;
  p.fresh.fetch_add(1, std::memory_order_relaxed);
  return user(h);
}

void* allocate_zeroed(size_t count, size_t size) {
  if (size != 0 && count > SIZE_MAX / size) return nullptr;
  void* q = allocate(count * size);
  if (q) std::memset(q, 0, count * size);
  return q;
}

void release(void* q) {
  if (!q) return;
  Header* h = header(q);
  if (h->magic != kMagic) std::abort();  // not ours: the recycler was installed after CHOLMOD allocated
  if (h->capacity < kMinBlock) {
    std::free(h);
    return;
  }
  Pool& p = pool();
  Header* evicted[kMaxKept];
  size_t nevicted = 0;
  {
    std::lock_guard<std::mutex> lock(p.mutex);
    const auto fits = [&] { return p.kept.size() < kMaxKept && p.kept_bytes + h->capacity <= kMaxBytes; };
    // Make room by evicting smaller kept blocks (the large factors matter most).
    while (!fits()) {
      const auto smallest = std::min_element(p.kept.begin(), p.kept.end());
      if (smallest == p.kept.end() || smallest->first >= h->capacity) break;
      evicted[nevicted++] = smallest->second;
      p.kept_bytes -= smallest->first;
      p.kept.erase(smallest);
    }
    if (fits()) {
      p.kept.emplace_back(h->capacity, h);
      p.kept_bytes += h->capacity;
      h = nullptr;
    }
  }
  for (size_t k = 0; k < nevicted; ++k) std::free(evicted[k]);
  std::free(h);
}

void* reallocate(void* q, size_t size) {
  if (!q) return allocate(size);
  Header* h = header(q);
  if (h->magic != kMagic) std::abort();
  if (size <= h->capacity) return q;  // never shrinks: CHOLMOD shrinks L after a simplicial factorization
  void* r = allocate(size);
  if (!r) return nullptr;  // q stays valid, as realloc's contract says
  std::memcpy(r, q, h->capacity);
  release(q);
  return r;
}

}  // namespace recycler

bool install_cholmod_block_recycler() {
#if defined(INCISE_ASAN)
  return false;
#else
  static const bool installed = [] {
    SuiteSparse_config.malloc_func = recycler::allocate;
    SuiteSparse_config.calloc_func = recycler::allocate_zeroed;
    SuiteSparse_config.realloc_func = recycler::reallocate;
    SuiteSparse_config.free_func = recycler::release;
    return true;
  }();
  return installed;
#endif
}

RecyclerStats cholmod_block_recycler_stats() {
  Pool& p = pool();
  std::lock_guard<std::mutex> lock(p.mutex);
  RecyclerStats s;
  s.reused = p.reused.load();
  s.grown = p.grown.load();
  s.fresh = p.fresh.load();
  s.kept_bytes = p.kept_bytes;
  return s;
}

}  // namespace incise
