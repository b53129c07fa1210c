#pragma once
// Growing a work array without a page fault per frame. During an incision
// the model gains DOFs nearly every frame, so arrays sized by it (K, A, the
// kept tangent blocks, the factor's float copy: 1-12 MB at 10k DOF) need a
// slightly larger buffer each cut frame; a plain resize then allocated a new
// one whose pages were faulted in on first touch (~250 per MB, 1-2 ms per
// cut frame on the stepping thread, more on the helpers). These reserve a
// quarter more whenever they must reallocate, so the next frames fit.
#include <cstddef>

namespace incise {

template <class V>
void reserve_with_headroom(V& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(n + n / 4);
}

template <class V>
void resize_with_headroom(V& v, std::size_t n) {
  reserve_with_headroom(v, n);
  v.resize(n);
}

template <class V, class T>
void assign_with_headroom(V& v, std::size_t n, const T& value) {
  reserve_with_headroom(v, n);
  v.assign(n, value);
}

template <class V, class It>
void assign_range_with_headroom(V& v, It first, It last) {
  reserve_with_headroom(v, static_cast<std::size_t>(last - first));
  v.assign(first, last);
}

}  // namespace incise
