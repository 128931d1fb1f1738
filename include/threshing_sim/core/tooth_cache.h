// threshing_sim core: compiled teeth kept between compilations of many models in one process
// (simulate --batch and --check-batch: a sweep's runs share few distinct teeth).
//
// compileTooth (beam.h) is a function of the drum radius and of the tooth's scene values
// alone (ToothCompileKey below: every ToothModel field it reads). A cache hit copies the fields
// compileTooth writes from the kept tooth, so a model compiled with a cache is bit for bit the
// model compiled without one (test_tooth_cache).
#pragma once

#include <cstddef>
#include <string>
#include <unordered_map>

#include "threshing_sim/core/model.h"

namespace threshing_sim {

// The inputs of compileTooth, as bytes: the drum radius and the tooth's scene values (mount
// angle, length, diameter, moduli, density, mode count, damping, stations, beam model, static
// correction, section rotation). Two teeth with equal keys compile to equal fields.
std::string toothCompileKey(double drum_radius_m, const ToothModel& tooth);

// Compiled teeth by toothCompileKey, at most kMaxTeeth and kMaxBytes (emptied when full: a
// sweep's runs come in order). The byte bound keeps a process's memory, and the page faults of
// new memory, small: a tooth of 40 modes holds megabytes of tables, and a kept tooth's memory
// is not reused by the next compilation. Not thread-safe: one per thread.
class ToothCache {
 public:
  static constexpr size_t kMaxTeeth = 256;       // teeth kept at most [-]
  static constexpr size_t kMaxBytes = 8u << 20;  // their tables' size at most [bytes]

  // compileTooth(drum_radius_m, tooth), or its kept result when an equal tooth was compiled
  // before (the fields compileTooth does not write keep their values). Throws as compileTooth.
  void compile(double drum_radius_m, ToothModel* tooth);

  size_t hits() const { return hits_; }      // compilations answered from the cache [-]
  size_t misses() const { return misses_; }  // compilations that ran compileTooth [-]
  size_t size() const { return teeth_.size(); }
  size_t bytes() const { return bytes_; }  // the kept teeth's tables [bytes]

 private:
  std::unordered_map<std::string, ToothModel> teeth_;  // compiled teeth by key
  size_t hits_ = 0;                                    // [-]
  size_t misses_ = 0;                                  // [-]
  size_t bytes_ = 0;                                   // [bytes]
};

// compileModel (model.h) with the teeth compiled through *teeth (null: no cache).
void compileModel(Model* model, ToothCache* teeth);

}  // namespace threshing_sim
