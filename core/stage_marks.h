// The names of a step's timing marks, for both backends' StageClock: mark 0
// is the start, mark k the end of the k-th named stage, whose time runs from
// mark k - 1 to mark k.
#pragma once

#include <cstring>
#include <stdexcept>
#include <string>

namespace sphray {

class StageMarks {
 public:
  static constexpr int kMax = 8;
  void clear() { n_ = 0; }
  // The index of a new mark named `stage` ("" for the start).
  int add(const char* stage) {
    if (n_ == kMax) throw std::logic_error("StageClock: more than 7 stages");
    names_[n_] = stage;
    return n_++;
  }
  int last() const { return n_ - 1; }
  // The mark that ends `stage`.
  int end_of(const char* stage) const {
    for (int k = 1; k < n_; ++k)
      if (std::strcmp(names_[k], stage) == 0) return k;
    throw std::logic_error(std::string("StageClock: no stage '") + stage + "'");
  }

 private:
  const char* names_[kMax] = {};
  int n_ = 0;
};

}  // namespace sphray
