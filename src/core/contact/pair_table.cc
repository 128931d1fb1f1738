// threshing_sim core: the pair table (pair_table.h), open addressing over a dense array.
#include "pair_table.h"

#include <algorithm>

namespace threshing_sim {
namespace internal {

std::uint64_t pairKey(const PairId& p) {
  return (static_cast<std::uint64_t>(p.kind) << 60) |
         (static_cast<std::uint64_t>(static_cast<std::uint32_t>(p.a)) << 30) |
         static_cast<std::uint64_t>(static_cast<std::uint32_t>(p.b));
}

namespace {
// Slot of a key in a table of n_slots = 2^k slots: a 64-bit multiplicative hash (the key's
// fields sit in the high and low bits, the product mixes them into the top bits).
size_t slotOf(std::uint64_t key, size_t n_slots) {
  const std::uint64_t mixed = (key ^ (key >> 31)) * 0x9E3779B97F4A7C15ull;
  return static_cast<size_t>(mixed >> 32) & (n_slots - 1);
}
}  // namespace

void PairTable::reserve(size_t n) {
  entries_.reserve(n);
  // Load factor at most 1/2.
  size_t n_slots = 16;
  while (n_slots < 2 * n) n_slots *= 2;
  if (n_slots > slots_.size()) rehash(n_slots);
}

void PairTable::rehash(size_t n_slots) {
  slots_.assign(n_slots, -1);
  for (size_t i = 0; i < entries_.size(); ++i) {
    size_t s = slotOf(entries_[i].first, n_slots);
    while (slots_[s] >= 0) s = (s + 1) & (n_slots - 1);
    slots_[s] = static_cast<int>(i);
  }
}

int PairTable::indexOf(std::uint64_t key) {
  if (slots_.empty()) rehash(16);
  // Linear probing to the key or an empty slot.
  size_t s = slotOf(key, slots_.size());
  while (slots_[s] >= 0) {
    if (entries_[slots_[s]].first == key) return slots_[s];
    s = (s + 1) & (slots_.size() - 1);
  }
  // New entry; grow the slots past half full (allocates only beyond the reserve).
  const int index = static_cast<int>(entries_.size());
  entries_.emplace_back(key, PairMemory());
  slots_[s] = index;
  if (2 * entries_.size() > slots_.size()) rehash(2 * slots_.size());
  return index;
}

PairMemory& PairTable::operator[](std::uint64_t key) { return entries_[indexOf(key)].second; }

const PairMemory* PairTable::find(std::uint64_t key) const {
  if (slots_.empty()) return nullptr;
  for (size_t s = slotOf(key, slots_.size());; s = (s + 1) & (slots_.size() - 1)) {
    if (slots_[s] < 0) return nullptr;
    if (entries_[slots_[s]].first == key) return &entries_[slots_[s]].second;
  }
}

void PairTable::clear() {
  entries_.clear();
  std::fill(slots_.begin(), slots_.end(), -1);
}

}  // namespace internal
}  // namespace threshing_sim
