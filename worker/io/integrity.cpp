// SPDX-License-Identifier: Apache-2.0
// Checkpoint checksums (integrity.h).
#include "io/integrity.h"

#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <map>
#include <sstream>

#include "io/hdf5_util.h"

namespace erg::io::detail {
namespace {

constexpr const char* kMagic = "erg-sum64";

// SplitMix64's finaliser (Steele, Lea & Flood 2014): a bijection of 64-bit
// words with full avalanche.
constexpr std::uint64_t mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// FNV-1a of the name, mixed: the key that makes each dataset's terms its own
// (so swapping two datasets, or renaming one, does not go unnoticed).
std::uint64_t key_of(const std::string& name) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char ch : name) h = (h ^ ch) * 0x100000001b3ULL;
  return mix(h);
}

inline std::uint64_t term(std::uint64_t key, std::uint64_t index, std::uint64_t bits) {
  return mix(mix(key ^ index) ^ bits);
}

template <class T>
std::uint64_t bits_of(T v) {
  if constexpr (sizeof(T) == 8) {
    std::uint64_t b = 0;
    std::memcpy(&b, &v, 8);
    return b;
  } else {
    std::uint32_t b = 0;
    std::memcpy(&b, &v, 4);
    return b;
  }
}

template <class T>
std::uint64_t sum_cells(std::uint64_t key, const T* v, const TileSlab& s, int global_nx) {
  std::uint64_t sum = 0;
  if (s.nx <= 0 || s.ny <= 0 || v == nullptr) return 0;
  for (int j = 0; j < s.ny; ++j) {
    const std::uint64_t row =
        static_cast<std::uint64_t>(s.y0 + j) * static_cast<std::uint64_t>(global_nx);
    const T* r = v + static_cast<std::size_t>(j) * static_cast<std::size_t>(s.nx);
    for (int i = 0; i < s.nx; ++i)
      sum += term(key, row + static_cast<std::uint64_t>(s.x0 + i), bits_of(r[i]));
  }
  return sum;
}

std::string hex(std::uint64_t v) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016" PRIx64, v);
  return buf;
}

// What a name is, for messages.
std::string what(const std::string& name) {
  if (name == "job_spec") return "the stored job spec";
  if (name == "attributes") return "the root attributes (step, grid, ledgers)";
  return "dataset '" + name + "'";
}

}  // namespace

std::uint64_t& Checksums::slot(const std::string& name) {
  for (auto& [n, v] : entries_)
    if (n == name) return v;
  entries_.emplace_back(name, 0);
  return entries_.back().second;
}

void Checksums::add_cells(const std::string& name, const std::int64_t* v, const TileSlab& slab,
                          int global_nx) {
  slot(name) += sum_cells(key_of(name), v, slab, global_nx);
}

void Checksums::add_cells(const std::string& name, const float* v, const TileSlab& slab,
                          int global_nx) {
  slot(name) += sum_cells(key_of(name), v, slab, global_nx);
}

void Checksums::add_text(const std::string& name, const std::string& s) {
  const std::uint64_t key = key_of(name);
  std::uint64_t sum = 0;
  for (std::size_t off = 0, i = 0; off < s.size(); off += 8, ++i) {
    std::uint64_t word = 0;  // little-endian, zero-padded
    for (std::size_t b = 0; b < 8 && off + b < s.size(); ++b)
      word |= static_cast<std::uint64_t>(static_cast<unsigned char>(s[off + b])) << (8 * b);
    sum += term(key, i, word);
  }
  sum += term(key, ~std::uint64_t{0}, s.size());
  slot(name) += sum;
}

void Checksums::allreduce(MPI_Comm comm) {
  std::vector<std::uint64_t> v;
  for (const auto& e : entries_) v.push_back(e.second);
  if (!v.empty())
    MPI_Allreduce(MPI_IN_PLACE, v.data(), static_cast<int>(v.size()), MPI_UINT64_T, MPI_SUM, comm);
  for (std::size_t k = 0; k < v.size(); ++k) entries_[k].second = v[k];
}

std::string Checksums::record() const {
  std::string out = std::string(kMagic) + "\n";
  for (const auto& [name, v] : entries_) out += name + " " + hex(v) + "\n";
  return out;
}

Checksums Checksums::parse(const std::string& record, const std::string& path) {
  std::istringstream in(record);
  std::string line;
  auto bad = [&](const std::string& why) {
    fail(path, "the checksums attribute is damaged (" + why + ")");
  };
  if (!std::getline(in, line) || line != kMagic) bad("it does not start with \"erg-sum64\"");
  Checksums c;
  while (std::getline(in, line)) {
    const auto sp = line.find(' ');
    const std::string name = line.substr(0, sp),
                      value = sp == std::string::npos ? "" : line.substr(sp + 1);
    if (name.empty() || value.size() != 16 ||
        value.find_first_not_of("0123456789abcdef") != std::string::npos)
      bad("line '" + line.substr(0, 80) + "'");
    for (const auto& e : c.entries_)
      if (e.first == name) bad("'" + name + "' appears twice");
    c.entries_.emplace_back(name, std::stoull(value, nullptr, 16));
  }
  return c;
}

std::string Checksums::mismatch(const Checksums& stored, bool complete) const {
  std::map<std::string, std::uint64_t> want(stored.entries_.begin(), stored.entries_.end());
  for (const auto& [name, v] : entries_) {
    auto it = want.find(name);
    if (it == want.end()) return "the checksums do not cover " + what(name);
    if (it->second != v)
      return "checksum of " + what(name) + " does not match (stored " + hex(it->second) +
             ", computed " + hex(v) + ")";
    want.erase(it);
  }
  if (complete && !want.empty())
    return "the checksums name " + what(want.begin()->first) + ", which the file lacks";
  return "";
}

Checksums checkpoint_cell_checksums(const Checkpoint& c, const TileSlab& slab,
                                    const std::array<bool, fields::kCount>& present) {
  Checksums s;
  for (int i = 0; i < fields::kCount; ++i) {
    const auto id = static_cast<fields::Id>(i);
    const fields::Info& f = fields::info(id);
    if (!f.state || !present[id]) continue;
    if (f.type == fields::Type::kUnits)
      s.add_cells(f.checkpoint, c.units[id].data(), slab, c.nx);
    else
      s.add_cells(f.checkpoint, c.reals[id].data(), slab, c.nx);
  }
  return s;
}

void add_checkpoint_attr_checksums(Checksums& sums, const Checkpoint& c, const std::string& format,
                                   std::int64_t format_version) {
  sums.add_text("job_spec", c.job_spec_json);
  // One line per attribute, each value length-prefixed so no two attribute
  // sets give the same text.
  std::string attrs;
  auto add = [&](const std::string& name, const std::string& value) {
    attrs += name + "=" + std::to_string(value.size()) + ":" + value + "\n";
  };
  add("format", format);
  add("format_version", std::to_string(format_version));
  add("step", std::to_string(c.step));
  add("nx", std::to_string(c.nx));
  add("ny", std::to_string(c.ny));
  for (const auto& [name, value] : c.ledger) add("ledger_" + name, value);
  sums.add_text("attributes", attrs);
}

}  // namespace erg::io::detail
