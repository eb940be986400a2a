// SPDX-License-Identifier: Apache-2.0
// Defaults: apply_defaults fills every parameter to the default documented in
// proto/erg/v1/job.proto, invents no layer source or wind regime, keeps what
// the job sets, is idempotent; to_json round-trips; the parameter table.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "job/spec.h"
#include "job_test_util.h"

namespace erg::job {
namespace {

namespace pb = google::protobuf;
using pb::util::MessageDifferencer;
using testing::minimal_spec;
using testing::parse_with_defaults;

// The model defaults as written in job.proto (copied by hand on purpose: a
// changed option must show up here).
const std::map<std::string, double> kModelDefaults = {
    {"time_step_days", 10},
    {"venturi_k", 0.005},
    {"warp_large_radius_m", 200},
    {"warp_large_weight", 0.8},
    {"warp_large_deviation", 30},
    {"warp_small_radius_m", 50},
    {"warp_small_weight", 0.2},
    {"warp_small_deviation", 5},
    {"warp_gradient_scale", 1},
    {"shadow_radius_m", 10},
    {"shadow_angle_min_deg", 10},
    {"shadow_angle_max_deg", 15},
    {"slab_m", 0.1},
    {"hop_time_s", 1},
    {"max_hop_m", 8},
    {"deposit_on_sand", 0.6},
    {"deposit_on_bedrock", 0.4},
    {"abrasion_k", 0},
    {"abrasion_sand_threshold_m", 0.25},
    {"reptation_k", 1},
    {"repose_deg", 33},
    {"repose_vegetated_deg", 45},
    {"avalanche_iterations", 10000},
    {"avalanche_kc", 1},
    {"avalanche_kc_damped", 0.5},
    {"bedrock_repose_deg", 68},
    {"bedrock_avalanche_iterations", 1},
    {"echo_cliff_deg", 50},
    {"echo_reach_m", 30},
    {"echo_gap_ratio", 1},
    {"echo_sticky_ratio", 3},
    {"echo_stickiness", 0.5},
    {"echo_erosion_k", 1},
};

TEST(Defaults, ModelParametersGetTheirDocumentedDefaults) {
  const JobSpec s = minimal_spec();
  const auto& m = s.model();
  EXPECT_EQ(m.venturi_k(), 0.005);
  EXPECT_EQ(m.repose_deg(), 33);
  EXPECT_EQ(m.slab_m(), 0.1);
  EXPECT_EQ(m.time_step_days(), 10);
  EXPECT_EQ(m.avalanche_iterations(), 10000);
  EXPECT_EQ(m.max_hop_m(), 8);
  EXPECT_EQ(m.deposit_on_sand(), 0.6);
  EXPECT_EQ(m.deposit_on_bedrock(), 0.4);
  EXPECT_EQ(m.bedrock_repose_deg(), 68);
  EXPECT_FALSE(m.bedrock_to_sand());
  EXPECT_FALSE(m.echo_dunes());

  // Every numeric model field is present after the defaults, with the value
  // of the table above; and the table covers every numeric model field.
  const pb::Descriptor* d = erg::v1::ModelParameters::descriptor();
  const pb::Reflection* r = m.GetReflection();
  int numeric = 0;
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    double v = 0;
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_DOUBLE)
      v = r->GetDouble(m, f);
    else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_INT64)
      v = static_cast<double>(r->GetInt64(m, f));
    else
      continue;
    ++numeric;
    EXPECT_TRUE(r->HasField(m, f)) << f->name() << " has no value after apply_defaults";
    auto it = kModelDefaults.find(f->name());
    ASSERT_NE(it, kModelDefaults.end()) << f->name() << " missing from the test's table";
    EXPECT_EQ(v, it->second) << f->name();
  }
  EXPECT_EQ(numeric, static_cast<int>(kModelDefaults.size()));
}

TEST(Defaults, RunSeedAndTransportDefaults) {
  const JobSpec s = minimal_spec();
  EXPECT_EQ(s.run().steps(), 1000);
  EXPECT_EQ(s.run().snapshot_every(), 100);
  EXPECT_EQ(s.run().checkpoint_every(), 500);
  EXPECT_TRUE(s.run().has_previews());
  EXPECT_TRUE(s.run().previews());
  EXPECT_TRUE(s.has_seed());
  EXPECT_EQ(s.seed(), 1);
  EXPECT_EQ(s.transport(), JobSpec::EXPECTED);
}

TEST(Defaults, UnsetEnumsTakeTheValueTheProtoNames) {
  const JobSpec s = parse_with_defaults(R"({
    "domain": {"nx": 64, "ny": 48, "cell_size_m": 1},
    "wind": {"constant": {"speed_mps": 0.3}, "speed_is": "SHEAR_VELOCITY"},
    "wind_primitives": [{"vortex": {"x_m": 1, "y_m": 1, "radius_m": 5, "peak_speed_mps": 1}}],
    "events": [{"step": 2, "wind": {"constant": {"speed_mps": 5}}}]
  })");
  EXPECT_EQ(s.transport(), JobSpec::EXPECTED);
  EXPECT_EQ(s.model().shadow_sampling(), erg::v1::ModelParameters::BILINEAR);
  EXPECT_EQ(s.model().repose(), erg::v1::ModelParameters::NEIGHBOUR_PAIRS);
  EXPECT_EQ(s.physics().flux_law(), erg::v1::PhysicalParameters::LETTAU_1978);
  EXPECT_EQ(s.wind_primitives(0).vortex().rotation(), erg::v1::Vortex::COUNTERCLOCKWISE);
  // Set values stay; an event's regime gets its own default.
  EXPECT_EQ(s.wind().speed_is(), erg::v1::WindRegime::SHEAR_VELOCITY);
  EXPECT_EQ(s.events(0).wind().speed_is(), erg::v1::WindRegime::MODEL);
  EXPECT_FALSE(s.model().bedrock_to_sand());
  EXPECT_FALSE(s.model().echo_dunes());
}

// Every default_text in job.proto names a value its enum has (a misspelt one
// would leave the field unset), and every enum field either has one or says
// in its doc what unset means.
TEST(Defaults, EveryEnumDefaultIsOneOfItsValues) {
  const pb::FileDescriptor* file = JobSpec::descriptor()->file();
  std::vector<const pb::Descriptor*> todo;
  for (int i = 0; i < file->message_type_count(); ++i) todo.push_back(file->message_type(i));
  int enums = 0;
  while (!todo.empty()) {
    const pb::Descriptor* d = todo.back();
    todo.pop_back();
    for (int i = 0; i < d->nested_type_count(); ++i) todo.push_back(d->nested_type(i));
    for (int i = 0; i < d->field_count(); ++i) {
      const pb::FieldDescriptor* f = d->field(i);
      const auto& s = f->options().GetExtension(erg::v1::spec);
      if (f->cpp_type() != pb::FieldDescriptor::CPPTYPE_ENUM) continue;
      ++enums;
      if (s.default_text().empty()) {
        EXPECT_FALSE(s.doc().empty()) << f->full_name() << ": no default and no doc";
        continue;
      }
      EXPECT_NE(f->enum_type()->FindValueByName(s.default_text()), nullptr)
          << f->full_name() << " default_text " << s.default_text();
      EXPECT_NE(s.default_text().find("UNSPECIFIED"), 0u) << f->full_name();
    }
  }
  EXPECT_GE(enums, 8);
}

TEST(Defaults, KeepsWhatTheJobSets) {
  const JobSpec s = parse_with_defaults(R"({
    "domain": {"nx": 64, "ny": 48, "cell_size_m": 2},
    "wind": {"constant": {"speed_mps": 10, "direction_deg": 0}},
    "transport": "STOCHASTIC", "seed": 0,
    "model": {"venturi_k": 0, "repose_deg": 30, "avalanche_iterations": 0},
    "run": {"steps": 0, "previews": false}
  })");
  EXPECT_EQ(s.model().venturi_k(), 0);  // explicitly 0, not the default
  EXPECT_EQ(s.model().repose_deg(), 30);
  EXPECT_EQ(s.model().avalanche_iterations(), 0);
  EXPECT_EQ(s.model().slab_m(), 0.1);
  EXPECT_EQ(s.run().steps(), 0);
  EXPECT_FALSE(s.run().previews());
  EXPECT_EQ(s.seed(), 0);
  EXPECT_EQ(s.transport(), JobSpec::STOCHASTIC);
  EXPECT_EQ(s.domain().cell_size_m(), 2);
}

TEST(Defaults, InventsNoLayerSourceWindRegimeOrRequiredValue) {
  JobSpec s = parse_json(R"({"domain": {"nx": 64}})");
  apply_defaults(s);
  EXPECT_FALSE(s.has_wind());
  EXPECT_EQ(s.events_size(), 0);
  EXPECT_FALSE(s.domain().has_ny());
  EXPECT_FALSE(s.domain().has_cell_size_m());
  for (const auto* layer : {&s.layers().bedrock(), &s.layers().sand(), &s.layers().vegetation(),
                            &s.layers().resistance()}) {
    EXPECT_FALSE(layer->has_constant());
    EXPECT_FALSE(layer->has_fbm());
    EXPECT_FALSE(layer->has_uniform());
    EXPECT_FALSE(layer->has_patches());
    EXPECT_EQ(layer->piles_size(), 0);
    EXPECT_FALSE(layer->has_map());
  }
  EXPECT_FALSE(s.layers().has_bedrock());
  EXPECT_FALSE(s.layers().has_sand());
}

TEST(Defaults, FillsNestedSourcesRegimesAndEvents) {
  const JobSpec s = parse_with_defaults(R"({
    "domain": {"nx": 64, "ny": 48, "cell_size_m": 1},
    "layers": {"bedrock": {"fbm": {}}, "sand": {"patches": {"coverage": 0.2}, "uniform": {},
               "piles": [{"x_m": 1, "y_m": 2, "height": 3, "radius_m": 4}]},
               "vegetation": {"map": {"path": "v.png"}}},
    "wind": {"rose": {"entries": [{"direction_deg": 0, "speed_mps": 1, "probability": 1}]}},
    "events": [{"step": 1, "sand": {"x_m": 1, "y_m": 1, "radius_m": 1, "height": 1}},
               {"step": 2, "wind": {"bidirectional": {"speed_mps": 5, "angle_deg": 90}}},
               {"step": 3, "wind": {"series": {"keyframes": [{"step": 0, "speed_mps": 1}]}}}]
  })");
  const auto& fbm = s.layers().bedrock().fbm();
  EXPECT_EQ(fbm.amplitude(), 1);
  EXPECT_EQ(fbm.offset(), 0);
  EXPECT_EQ(fbm.wavelength_m(), 256);
  EXPECT_EQ(fbm.octaves(), 5);
  EXPECT_EQ(fbm.gain(), 0.5);
  EXPECT_EQ(fbm.anisotropy(), 1);
  const auto& sand = s.layers().sand();
  EXPECT_EQ(sand.patches().coverage(), 0.2);
  EXPECT_EQ(sand.patches().radius_m(), 20);
  EXPECT_EQ(sand.patches().height(), 2);
  EXPECT_EQ(sand.patches().falloff_m(), 5);
  EXPECT_EQ(sand.uniform().min(), 0);
  EXPECT_EQ(sand.uniform().max(), 1);
  EXPECT_EQ(sand.piles(0).shape(), erg::v1::Pile::CONE);
  EXPECT_EQ(s.layers().vegetation().map().scale(), 1);
  EXPECT_EQ(s.layers().vegetation().map().dataset(), "/data");
  // Unset: guessed from the file's extension, so no default is invented.
  EXPECT_EQ(s.layers().vegetation().map().format(), erg::v1::MapFile::FORMAT_UNSPECIFIED);
  EXPECT_EQ(s.layers().vegetation().map().offset(), 0);
  EXPECT_EQ(s.wind().rose().hold_steps(), 1);
  EXPECT_EQ(s.wind().rose().sector_width_deg(), 0);
  EXPECT_EQ(s.wind().rose().entries_size(), 1);
  EXPECT_EQ(s.events(0).sand().falloff_m(), 0);
  EXPECT_TRUE(s.events(0).sand().has_falloff_m());
  const auto& bi = s.events(1).wind().bidirectional();
  EXPECT_EQ(bi.flux_ratio(), 1);
  EXPECT_EQ(bi.period_steps(), 20);
  EXPECT_EQ(bi.direction_deg(), 0);
  EXPECT_TRUE(bi.has_direction_deg());
  const auto& series = s.events(2).wind().series();
  EXPECT_EQ(series.period_steps(), 0);
  EXPECT_TRUE(series.keyframes(0).has_direction_deg());
  EXPECT_FALSE(s.events(2).wind().has_rose());
}

const char* kRichJob = R"({
  "name": "round trip", "transport": "stochastic", "seed": "123456789012",
  "domain": {"nx": 96, "ny": 80, "cell_size_m": 0.75},
  "layers": {
    "bedrock": {"constant": -1.25, "fbm": {"amplitude": 3.3, "ridged": true, "anisotropy": 2.5}},
    "sand": {"patches": {"coverage": 0.3, "radius_m": 3.5},
             "piles": [{"x_m": 5.1, "y_m": 7.9, "height": 2, "radius_m": 3, "shape": "CYLINDER"}]},
    "vegetation": {"map": {"path": "v.h5", "format": "HDF5", "dataset": "/v", "scale": 0.001}}
  },
  "wind": {"rose": {"entries": [{"direction_deg": 10.5, "speed_mps": 5, "probability": 0.3},
                                 {"direction_deg": -90, "speed_mps": 7.25, "probability": 0.7}],
                     "hold_steps": 3}},
  "events": [{"step": 5, "vegetation": {"x_m": 1, "y_m": 2, "radius_m": 3, "density": 0.1}},
             {"step": 6, "wind": {"constant": {"speed_mps": 1e-3}}}],
  "model": {"bedrock_to_sand": true, "venturi_k": 0.0071}
})";

TEST(Defaults, Idempotent) {
  JobSpec once = parse_with_defaults(kRichJob);
  JobSpec twice = once;
  apply_defaults(twice);
  EXPECT_TRUE(MessageDifferencer::Equals(once, twice));
  EXPECT_EQ(once.SerializeAsString(), twice.SerializeAsString());
  JobSpec m = minimal_spec();
  JobSpec m2 = m;
  apply_defaults(m2);
  EXPECT_TRUE(MessageDifferencer::Equals(m, m2));
}

TEST(ToJson, RoundTripsToAnEqualMessage) {
  for (const char* text : {kRichJob, testing::kMinimalJob}) {
    const JobSpec spec = parse_with_defaults(text);
    const std::string json = to_json(spec);
    const JobSpec back = parse_json(json, "round-trip");
    std::string diff;
    MessageDifferencer d;
    d.ReportDifferencesToString(&diff);
    EXPECT_TRUE(d.Compare(spec, back)) << diff << "\n" << json;
    // Also without the defaults: what the user wrote survives as written.
    const JobSpec raw = parse_json(text);
    EXPECT_TRUE(MessageDifferencer::Equals(raw, parse_json(to_json(raw))));
  }
}

TEST(ToJson, UsesProtoFieldNamesAndIncludesDefaults) {
  const std::string json = to_json(minimal_spec());
  EXPECT_NE(json.find("\"cell_size_m\""), std::string::npos) << json;
  EXPECT_EQ(json.find("cellSizeM"), std::string::npos) << json;
  EXPECT_NE(json.find("\"venturi_k\": 0.005"), std::string::npos) << json;
  EXPECT_NE(json.find("\"repose_deg\": 33"), std::string::npos) << json;
  EXPECT_NE(json.find("\"transport\": \"EXPECTED\""), std::string::npos) << json;
  EXPECT_NE(json.find('\n'), std::string::npos) << "not indented";
}

// The table row of a field: "| `path` | default | allowed | meaning |".
std::string table_row(const std::string& table, const std::string& path) {
  std::istringstream in(table);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("| `" + path + "` |", 0) == 0) return line;
  return "";
}

TEST(ParameterTable, ListsVenturiWithDefaultRangeAndSource) {
  const std::string t = parameter_table_markdown();
  const std::string row = table_row(t, "model.venturi_k");
  ASSERT_FALSE(row.empty()) << t;
  EXPECT_NE(row.find("| 0.005 |"), std::string::npos) << row;
  EXPECT_NE(row.find("[0, 1] 1/m"), std::string::npos) << row;
  EXPECT_NE(row.find("P19 4.2; N24 eq. 1"), std::string::npos) << row;
}

// The unknown-field error points users at `erg params` for every field, so
// every field of every message a job can hold has a row (enums with their
// values, booleans, text).
TEST(ParameterTable, ListsEveryFieldWithItsValues) {
  const std::string t = parameter_table_markdown();
  std::vector<const pb::Descriptor*> todo = {JobSpec::descriptor()};
  std::set<std::string> seen;
  while (!todo.empty()) {
    const pb::Descriptor* d = todo.back();
    todo.pop_back();
    if (!seen.insert(d->full_name()).second) continue;
    for (int i = 0; i < d->field_count(); ++i) {
      const pb::FieldDescriptor* f = d->field(i);
      if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
        todo.push_back(f->message_type());
        continue;
      }
      const std::string tail = "." + f->name() + "` |";
      const std::string top = "| `" + f->name() + "` |";
      EXPECT_TRUE(t.find(tail) != std::string::npos || t.find(top) != std::string::npos)
          << f->full_name() << " has no row";
    }
  }
  EXPECT_NE(table_row(t, "transport").find("| EXPECTED | EXPECTED, STOCHASTIC |"),
            std::string::npos)
      << table_row(t, "transport");
  EXPECT_NE(table_row(t, "model.repose").find("| NEIGHBOUR_PAIRS | NEIGHBOUR_PAIRS, ISOTROPIC |"),
            std::string::npos)
      << table_row(t, "model.repose");
  EXPECT_NE(table_row(t, "model.shadow_sampling").find("| BILINEAR | BILINEAR, CUBIC |"),
            std::string::npos);
  EXPECT_NE(table_row(t, "physics.flux_law").find("| LETTAU_1978 |"), std::string::npos);
  EXPECT_NE(table_row(t, "model.echo_dunes").find("| false | true, false |"), std::string::npos)
      << table_row(t, "model.echo_dunes");
  EXPECT_NE(table_row(t, "layers.sand.map.dataset").find("| /data | text |"), std::string::npos)
      << table_row(t, "layers.sand.map.dataset");
  EXPECT_NE(table_row(t, "layers.sand.map.format").find("| - | HDF5, PNG16, GEOTIFF, EXR |"),
            std::string::npos)
      << table_row(t, "layers.sand.map.format");
}

TEST(ParameterTable, DefaultsAreWrittenPlainly) {
  const std::string t = parameter_table_markdown();
  // Every model parameter has a row with its default as a plain number.
  for (const auto& [name, def] : kModelDefaults) {
    const std::string row = table_row(t, "model." + name);
    ASSERT_FALSE(row.empty()) << name;
    std::ostringstream want;
    want << "| " << def << " |";
    EXPECT_NE(row.find(want.str()), std::string::npos) << row << " should show " << want.str();
  }
  EXPECT_NE(table_row(t, "model.time_step_days").find("| 10 | (0, 36500] days |"),
            std::string::npos)
      << table_row(t, "model.time_step_days");
  EXPECT_NE(table_row(t, "domain.nx").find("| required | [8, 1048576] cells |"), std::string::npos)
      << table_row(t, "domain.nx");
  EXPECT_NE(table_row(t, "domain.cell_size_m").find("[0.01, 1000] m"), std::string::npos)
      << table_row(t, "domain.cell_size_m");
  EXPECT_NE(table_row(t, "run.previews").find("| true |"), std::string::npos);
  EXPECT_NE(table_row(t, "wind.bidirectional.angle_deg").find("[0, 180] deg"), std::string::npos);
  EXPECT_FALSE(table_row(t, "seed").empty());
  EXPECT_FALSE(table_row(t, "events[].sand.falloff_m").empty());
}

// ---- overrides ------------------------------------------------------------------

TEST(Overrides, SetOnlyWhatIsGiven) {
  JobSpec s = minimal_spec();
  apply_overrides(s, Overrides{});
  EXPECT_EQ(s.run().steps(), 1000);
  EXPECT_EQ(s.run().snapshot_every(), 100);
  EXPECT_EQ(s.run().checkpoint_every(), 500);

  Overrides o;
  o.steps = 7;
  apply_overrides(s, o);
  EXPECT_EQ(s.run().steps(), 7);
  EXPECT_EQ(s.run().snapshot_every(), 100);
  EXPECT_EQ(s.run().checkpoint_every(), 500);

  o = Overrides{};
  o.snapshot_every = 0;
  o.checkpoint_every = 3;
  apply_overrides(s, o);
  EXPECT_EQ(s.run().steps(), 7);
  EXPECT_EQ(s.run().snapshot_every(), 0);
  EXPECT_EQ(s.run().checkpoint_every(), 3);
  EXPECT_TRUE(validate(s).empty());
}

TEST(Overrides, OverriddenStepsSurviveDefaults) {
  JobSpec s = parse_json(testing::kMinimalJob);
  Overrides o;
  o.steps = 0;
  apply_overrides(s, o);
  apply_defaults(s);
  EXPECT_EQ(s.run().steps(), 0);
  EXPECT_EQ(s.run().snapshot_every(), 100);
}

}  // namespace
}  // namespace erg::job
