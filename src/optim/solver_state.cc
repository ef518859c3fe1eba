#include "solver_state.h"

#include <cstring>
#include <sstream>

#include "banmo/model/model.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

void AppendPod(std::string* out, const void* data, size_t bytes) {
  out->append(static_cast<const char*>(data), bytes);
}
template <typename T>
void Append(std::string* out, const T& v) {
  AppendPod(out, &v, sizeof(T));
}
// Throws unless `count` items of `item_bytes` each remain after *pos: a
// damaged length field must not allocate (or read) beyond the file.
void NeedBytes(const std::string& in, size_t pos, uint64_t count, size_t item_bytes) {
  if (pos > in.size() || count > (in.size() - pos) / item_bytes) {
    ThrowInputError("checkpoint state.bin: truncated or damaged (a length of ", count,
                    " items at byte ", pos, " runs past the end of the file)");
  }
}

template <typename T>
T Read(const std::string& in, size_t* pos) {
  if (*pos + sizeof(T) > in.size()) ThrowInputError("checkpoint state.bin: truncated");
  T v;
  std::memcpy(&v, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return v;
}

}  // namespace

std::string SolverState::Serialize() const {
  std::string out = "BANMOST1";
  Append(&out, stage);
  Append(&out, batch);
  Append(&out, total_batches);
  Append(&out, lm_radius);
  std::ostringstream rs;
  rs << rng;
  const std::string r = rs.str();
  Append(&out, static_cast<uint64_t>(r.size()));
  out += r;
  Append(&out, static_cast<uint64_t>(adam.size()));
  for (const auto& [name, mo] : adam) {
    Append(&out, static_cast<uint64_t>(name.size()));
    out += name;
    Append(&out, static_cast<uint64_t>(mo.m.size()));
    AppendPod(&out, mo.m.data(), sizeof(double) * mo.m.size());
    AppendPod(&out, mo.v.data(), sizeof(double) * mo.v.size());
    Append(&out, mo.steps);
  }
  Append(&out, static_cast<uint64_t>(error_cache.size()));
  AppendPod(&out, error_cache.data(), sizeof(RaySampler::CachedPixel) * error_cache.size());
  for (int k = 0; k < 3; ++k) Append(&out, bounds.min()[k]);
  for (int k = 0; k < 3; ++k) Append(&out, bounds.max()[k]);
  return out;
}

void SolverState::Deserialize(const std::string& in) {
  if (in.compare(0, 8, "BANMOST1") != 0) ThrowInputError("checkpoint state.bin: bad header");
  size_t pos = 8;
  stage = Read<int>(in, &pos);
  batch = Read<int>(in, &pos);
  total_batches = Read<int>(in, &pos);
  lm_radius = Read<double>(in, &pos);
  const uint64_t rn = Read<uint64_t>(in, &pos);
  NeedBytes(in, pos, rn, 1);
  std::istringstream rs(in.substr(pos, rn));
  rs >> rng;
  if (rs.fail()) ThrowInputError("checkpoint state.bin: damaged random-number state");
  pos += rn;
  const uint64_t na = Read<uint64_t>(in, &pos);
  adam.clear();
  for (uint64_t i = 0; i < na; ++i) {
    const uint64_t ln = Read<uint64_t>(in, &pos);
    NeedBytes(in, pos, ln, 1);
    const std::string name = in.substr(pos, ln);
    pos += ln;
    const uint64_t n = Read<uint64_t>(in, &pos);
    NeedBytes(in, pos, n, 2 * sizeof(double));
    Moments mo;
    mo.m.resize(n);
    mo.v.resize(n);
    for (auto& x : mo.m) x = Read<double>(in, &pos);
    for (auto& x : mo.v) x = Read<double>(in, &pos);
    mo.steps = Read<int64_t>(in, &pos);
    adam[name] = std::move(mo);
  }
  const uint64_t nc = Read<uint64_t>(in, &pos);
  NeedBytes(in, pos, nc, sizeof(RaySampler::CachedPixel));
  error_cache.resize(nc);
  for (auto& c : error_cache) c = Read<RaySampler::CachedPixel>(in, &pos);
  Eigen::Vector3d lo, hi;
  for (int k = 0; k < 3; ++k) lo[k] = Read<double>(in, &pos);
  for (int k = 0; k < 3; ++k) hi[k] = Read<double>(in, &pos);
  bounds = Eigen::AlignedBox3d(lo, hi);
}

namespace {

constexpr const char kBasisSuffix[] = "_basis";
constexpr size_t kBasisSuffixLength = sizeof(kBasisSuffix) - 1;

bool IsBasisMomentsName(const std::string& name) {
  return name.size() > kBasisSuffixLength &&
         name.compare(name.size() - kBasisSuffixLength, kBasisSuffixLength, kBasisSuffix) == 0;
}

}  // namespace

std::string BasisMomentsName(int video, ParameterGroup group) {
  CHECK(group == ParameterGroup::kBonesT || group == ParameterGroup::kRoot);
  return "video" + std::to_string(video) +
         (group == ParameterGroup::kBonesT ? "/bones_t" : "/root_delta") + kBasisSuffix;
}

std::optional<ParameterGroup> AdamMomentsGroup(const std::string& name) {
  if (IsBasisMomentsName(name)) {
    return Model::BlockGroup(name.substr(0, name.size() - kBasisSuffixLength));
  }
  return Model::BlockGroup(name);
}

void SolverState::DropAdamMoments(ParameterGroupSet groups) {
  for (auto m = adam.begin(); m != adam.end();) {
    const std::optional<ParameterGroup> group = AdamMomentsGroup(m->first);
    m = group && groups.Contains(*group) ? adam.erase(m) : std::next(m);
  }
}

void SolverState::DropAdamBasisMoments() {
  for (auto m = adam.begin(); m != adam.end();) {
    m = IsBasisMomentsName(m->first) ? adam.erase(m) : std::next(m);
  }
}

}  // namespace banmo
