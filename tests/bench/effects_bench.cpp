// Nanoseconds per pixel of the effect chain after the cast: the daemon's budget is a few ns
// (DESIGN.md "Speed"). One 128-beam column per call, the column index advancing as in a frame.
#include <benchmark/benchmark.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/random/counter_rng.h"

namespace {

using lidartwin::ColumnContext;
using lidartwin::EffectChain;
using lidartwin::IdealReturn;
using lidartwin::Measurement;
using nlohmann::json;

constexpr size_t kBeams = 128;

// Inverted rate of (pixels * 1e-9): nanoseconds per pixel.
void report_ns_per_pixel(benchmark::State& state) {
  state.counters["ns_per_pixel"] = benchmark::Counter(static_cast<double>(state.iterations() * kBeams) * 1e-9,
                                                      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// A plausible column: floor, walls and a few misses, ranges 0.5-90 m, mixed reflectivity.
std::vector<IdealReturn> typical_column() {
  std::vector<IdealReturn> column(kBeams);
  for (size_t b = 0; b < kBeams; ++b) {
    IdealReturn& in = column[b];
    if (b % 17 == 0) continue;  // sky
    in.range_m = 0.5f + 90.0f * static_cast<float>((b * 37) % kBeams) / static_cast<float>(kBeams);
    in.reflectivity = 0.05f + 0.9f * static_cast<float>((b * 11) % 13) / 13.0f;
    in.cos_incidence = 0.2f + 0.8f * static_cast<float>((b * 5) % 7) / 7.0f;
    in.retroreflective = b == 64;
  }
  return column;
}

const json kRadiometry = {{"name", "radiometry"}};
const json kPiecewise = {
    {"name", "range_noise_piecewise"},
    {"points_m", json::parse("[[0.3, 0.007], [0.98, 0.007], [1.02, 0.01], [19.6, 0.01], [20.4, 0.02], "
                             "[49.0, 0.02], [51.0, 0.05], [100, 0.05]]")}};
const json kLinear = {
    {"name", "range_noise_linear"}, {"sigma0_m", 0.01}, {"sigma_max_m", 0.15}, {"range_max_m", 100.0}};
const json kLimits = {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}};
const json kQuantization = {{"name", "range_quantization"}};
const json kDropout = {{"name", "dropout"}};
const json kIncidence = {{"name", "incidence"}, {"divergence_rad", 0.00314}};

void run_chain(benchmark::State& state, const json& effects) {
  const EffectChain chain = EffectChain::from_json(effects, "bench");
  const auto column = typical_column();
  std::vector<Measurement> out(kBeams);
  ColumnContext context;
  context.seed = 1;
  context.range_step_m = 0.008f;
  for (auto _ : state) {
    chain.simulate(column, context, out);
    benchmark::DoNotOptimize(out.data());
    context.column = (context.column + 1) % 2048;
    if (context.column == 0) ++context.frame;
  }
  report_ns_per_pixel(state);
}

// Table I's chain alone: radiometry, the datasheet's sigma(r), limits, quantization.
void BM_TableChain(benchmark::State& state) {
  run_chain(state, json::array({kRadiometry, kPiecewise, kLimits, kQuantization}));
}
// The OS1 datasheet profiles' chain (profiles/os1-128.json): Table I's plus incidence (E4) and
// detection from the signal (E5).
void BM_DatasheetChain(benchmark::State& state) {
  run_chain(state, json::array({kRadiometry, kPiecewise, kIncidence, kDropout, kLimits, kQuantization}));
}
void BM_PaperChain(benchmark::State& state) {
  run_chain(state, json::array({kRadiometry, kLinear, kLimits, kQuantization}));
}
void BM_Radiometry(benchmark::State& state) { run_chain(state, json::array({kRadiometry})); }
void BM_RangeNoisePiecewise(benchmark::State& state) { run_chain(state, json::array({kPiecewise})); }
void BM_RangeNoiseLinear(benchmark::State& state) { run_chain(state, json::array({kLinear})); }
void BM_Dropout(benchmark::State& state) { run_chain(state, json::array({kRadiometry, kDropout})); }
void BM_Incidence(benchmark::State& state) { run_chain(state, json::array({kIncidence})); }
void BM_LimitsAndQuantization(benchmark::State& state) { run_chain(state, json::array({kLimits, kQuantization})); }
void BM_Empty(benchmark::State& state) { run_chain(state, json::array()); }

// The normal draws themselves, per pixel stream included.
template <bool kZiggurat>
void BM_NormalDraw(benchmark::State& state) {
  const lidartwin::ColumnStreams streams(1, 0, 0, 7);
  std::vector<double> out(kBeams);
  uint32_t pair = 0;
  for (auto _ : state) {
    for (uint32_t b = 0; b < kBeams; ++b)
      out[b] = kZiggurat ? streams(b).normal_ziggurat(pair) : streams(b).normal(pair);
    benchmark::DoNotOptimize(out.data());
    ++pair;
  }
  report_ns_per_pixel(state);
}

}  // namespace

BENCHMARK(BM_TableChain);
BENCHMARK(BM_DatasheetChain);
BENCHMARK(BM_PaperChain);
BENCHMARK(BM_Radiometry);
BENCHMARK(BM_RangeNoisePiecewise);
BENCHMARK(BM_RangeNoiseLinear);
BENCHMARK(BM_Dropout);
BENCHMARK(BM_Incidence);
BENCHMARK(BM_LimitsAndQuantization);
BENCHMARK(BM_Empty);
BENCHMARK(BM_NormalDraw<true>)->Name("BM_NormalZiggurat");
BENCHMARK(BM_NormalDraw<false>)->Name("BM_NormalBoxMuller");

BENCHMARK_MAIN();
