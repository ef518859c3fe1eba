// model/model_options_fields.h: every option struct lists each of its fields
// once, under a unique key, and the lists reach every nested struct.
#include "banmo/model/model_options_fields.h"

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "banmo/model/model.h"

namespace banmo {
namespace {

// Records the keys and field addresses one VisitFields call reports.
struct FieldRecorder {
  std::vector<std::string> keys;
  std::vector<const void*> begin, end;
  template <class T>
  void operator()(const char* key, T& field) {
    keys.push_back(key);
    begin.push_back(&field);
    end.push_back(&field + 1);
  }
};

// Keys unique, fields disjoint and inside the struct.
template <class S>
FieldRecorder CheckFields(S& s) {
  FieldRecorder r;
  VisitFields(r, s);
  EXPECT_FALSE(r.keys.empty());
  EXPECT_EQ(std::set<std::string>(r.keys.begin(), r.keys.end()).size(), r.keys.size());
  const char* lo = reinterpret_cast<const char*>(&s);
  const char* hi = reinterpret_cast<const char*>(&s + 1);
  for (size_t i = 0; i < r.keys.size(); ++i) {
    SCOPED_TRACE(r.keys[i]);
    EXPECT_GE(static_cast<const char*>(r.begin[i]), lo);
    EXPECT_LE(static_cast<const char*>(r.end[i]), hi);
    for (size_t j = 0; j < i; ++j) {
      const bool disjoint =
          static_cast<const char*>(r.end[j]) <= static_cast<const char*>(r.begin[i]) ||
          static_cast<const char*>(r.end[i]) <= static_cast<const char*>(r.begin[j]);
      EXPECT_TRUE(disjoint) << "overlaps " << r.keys[j];
    }
  }
  return r;
}

TEST(ModelOptionsFields, EveryStructListsDistinctFieldsUnderUniqueKeys) {
  ModelOptions options;
  const FieldRecorder model = CheckFields(options);
  CheckFields(options.field);
  CheckFields(options.field.position_encoding);
  CheckFields(options.delta_skinning);
  CheckFields(options.auto_size);
  // The nested structs are reached from ModelOptions under their keys.
  const std::set<std::string> keys(model.keys.begin(), model.keys.end());
  for (const char* nested : {"field", "delta_skinning", "auto_size", "num_bones", "scene_scale"}) {
    EXPECT_TRUE(keys.count(nested)) << nested;
  }
}

// Sets every int field to 7, descending into the positional encoding.
struct SetInts {
  void operator()(const char*, int& v) { v = 7; }
  void operator()(const char*, PositionalEncodingOptions& o) { VisitFields(*this, o); }
  template <class T>
  void operator()(const char*, T&) {}
};

TEST(ModelOptionsFields, VisitingReachesTheFieldsThemselves) {
  // Writing through the visitor changes the options (the lists hold
  // references, not copies).
  CanonicalFieldOptions field;
  SetInts set;
  VisitFields(set, field);
  EXPECT_EQ(field.sdf_width, 7);
  EXPECT_EQ(field.color_layers, 7);
  EXPECT_EQ(field.position_encoding.num_bands, 7);
  AutoSizeOptions auto_size;
  VisitFields(set, auto_size);
  EXPECT_EQ(auto_size.max_bones, 7);
  EXPECT_EQ(auto_size.eval_rays, 7);
}

}  // namespace
}  // namespace banmo
