#pragma once
// A histogram with fixed bucket bounds, kept the way Prometheus exposes one (cumulative counts per
// upper bound, a count and a sum), for measurements taken on a bus loop: observe() is a short scan
// and three additions, no allocation and no lock, so it may sit on the loop's hot path. Not
// thread-safe: one owner thread (or its owner's lock) per histogram; readers take a copy there.

#include <array>
#include <cstddef>
#include <cstdint>

namespace lb {

template <std::size_t N>
class Histogram {
 public:
  using Bounds = std::array<double, N>;

  // bounds: ascending, and outliving the histogram (a static constant: the bounds are part of
  // what a metric means, fixed and documented).
  explicit constexpr Histogram(const Bounds& bounds) : bounds_(&bounds) {}

  void observe(double value) {
    std::size_t i = 0;
    while (i < N && value > (*bounds_)[i]) ++i;
    if (i < N) ++counts_[i];  // beyond the last bound: in count() only (Prometheus' +Inf bucket)
    ++count_;
    sum_ += value;
  }

  static constexpr std::size_t size() { return N; }
  const Bounds& bounds() const { return *bounds_; }
  // Observations at most bounds()[i].
  std::uint64_t cumulative(std::size_t i) const {
    std::uint64_t c = 0;
    for (std::size_t k = 0; k <= i && k < N; ++k) c += counts_[k];
    return c;
  }
  std::uint64_t count() const { return count_; }
  double sum() const { return sum_; }

 private:
  const Bounds* bounds_;
  std::array<std::uint64_t, N> counts_{};  // per bucket, not cumulative: observe() touches one
  std::uint64_t count_ = 0;
  double sum_ = 0.0;
};

}  // namespace lb
