// The chain: profile chains against predict, independent and deterministic noise per effect.
#include "effects/effects_test_support.h"

using namespace effects_test;  // NOLINT(google-build-using-namespace): the shared test helpers

TEST(EffectChain, ProfileChainSamplesMatchPrediction) {
  // The os1-64 chain on the RNG15 wire (8 mm): noise, limits and quantization together.
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}},
                                                  piecewise(kKnotsOs1),
                                                  {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}},
                                                  {{"name", "range_quantization"}}}));
  ColumnContext rng15;
  rng15.range_step_m = 0.008f;
  for (const float r : {2.0f, 15.0f, 35.0f, 70.0f}) {
    const Prediction p = chain.predict(surface(r), rng15);
    expect_agreement(sample(chain, surface(r), 128 * 1024, rng15), static_cast<double>(r) + p.bias_m,
                     std::sqrt(p.variance_m2), p.p_detect, label("os1 chain, 8 mm", r), 5.0, 0.01);
  }
}

TEST(EffectChain, EffectsDrawIndependentNoise) {
  // Two copies of one noise effect get different stream ids: their variances add.
  const EffectChain twice = chain_of(json::array({kLinearOs1, kLinearOs1}));
  EXPECT_NE(twice.effects()[0]->stream_id(), twice.effects()[1]->stream_id());
  const Prediction p = twice.predict(surface(30.0f), {});
  expect_agreement(sample(twice, surface(30.0f), 64 * 1024), 30.0, std::sqrt(p.variance_m2), 1.0,
                   "two linear noises r=30");
}

namespace {
std::vector<Measurement> render_columns(const EffectChain& chain, uint64_t seed, const std::vector<uint32_t>& order) {
  std::vector<IdealReturn> column;
  for (size_t b = 0; b < kBeams; ++b) column.push_back(surface(0.5f + 0.8f * static_cast<float>(b), 0.3f));
  std::vector<Measurement> all(order.size() * kBeams);
  for (const uint32_t c : order) {
    ColumnContext context;
    context.seed = seed;
    context.frame = 3;
    context.column = c;
    chain.simulate(column, context, std::span(all).subspan(c * kBeams, kBeams));
  }
  return all;
}

bool same(const std::vector<Measurement>& a, const std::vector<Measurement>& b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const Measurement& x, const Measurement& y) {
    return x.range_m == y.range_m && x.signal_photons == y.signal_photons && x.reflectivity == y.reflectivity &&
           x.near_ir_photons == y.near_ir_photons;
  });
}
}  // namespace

TEST(EffectChain, DeterministicInAnyColumnOrderAndThreadSplit) {
  const EffectChain chain = chain_of(json::array({{{"name", "radiometry"}},
                                                  kLinearOs1,
                                                  {{"name", "dropout"}},
                                                  {{"name", "range_limits"}, {"min_m", 0.3}, {"max_m", 100.0}},
                                                  {{"name", "range_quantization"}}}));
  std::vector<uint32_t> order(512);
  std::iota(order.begin(), order.end(), 0u);
  const auto reference = render_columns(chain, 42, order);
  EXPECT_TRUE(same(reference, render_columns(chain, 42, order)));
  EXPECT_FALSE(same(reference, render_columns(chain, 43, order)));

  std::mt19937 shuffle_engine(2024);  // fixed seed: the order only needs to differ from 0..n
  std::shuffle(order.begin(), order.end(), shuffle_engine);
  EXPECT_TRUE(same(reference, render_columns(chain, 42, order)));

  std::vector<Measurement> threaded(reference.size());
  std::vector<std::thread> threads;
  for (uint32_t t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      std::vector<uint32_t> mine;
      for (size_t j = t; j < order.size(); j += 4) mine.push_back(order[j]);
      std::vector<IdealReturn> column;
      for (size_t b = 0; b < kBeams; ++b) column.push_back(surface(0.5f + 0.8f * static_cast<float>(b), 0.3f));
      for (const uint32_t c : mine) {
        ColumnContext context;
        context.seed = 42;
        context.frame = 3;
        context.column = c;
        chain.simulate(column, context, std::span(threaded).subspan(c * kBeams, kBeams));
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_TRUE(same(reference, threaded));
}

TEST(EffectChain, ReplacingKeepsOtherEffectsNoise) {
  const EffectChain chain =
      chain_of(json::array({{{"name", "radiometry"}}, kLinearOs1, {{"name", "range_quantization"}}}));
  const auto& noise = *chain.effects()[1];
  const std::vector<double> values{0.02, 0.3, 100.0};
  const EffectChain refit = chain.replacing(1, noise.with_parameters(values));
  EXPECT_EQ(refit.effects()[1]->stream_id(), noise.stream_id());
  EXPECT_EQ(refit.effects()[1]->parameters()[1].value, 0.3);
  const EffectChain longer = chain.with_effect(chain.effects()[1]);
  EXPECT_EQ(longer.effects().size(), 4u);
  EXPECT_NE(longer.effects()[3]->stream_id(), noise.stream_id());  // a new place, a new stream
}

// Effects that act on returns walk the chain's list of them; a return an earlier effect added (a
// false alarm on a sky pixel, E14) is listed again, so the noise after it moves it too, and a
// return dropped earlier is left alone.
TEST(EffectChain, ReturnsAddedByAnEffectGetTheLaterEffects) {
  const json radiometry = {{"name", "radiometry"}, {"sky_photons", 1000.0}};
  const json alarms = {{"name", "false_alarms"}, {"probability_at_reference", 0.5}};
  const json noise = {{"name", "range_noise_linear"}, {"sigma0_m", 0.5}, {"sigma_max_m", 0.5}, {"range_max_m", 100.0}};
  const EffectChain without = chain_of(json::array({radiometry, alarms}));
  const EffectChain with = chain_of(json::array({radiometry, alarms, noise}));
  std::vector<IdealReturn> column(kBeams);  // sky: no hits
  for (size_t b = 0; b < kBeams; b += 2) column[b] = surface(20.0f);
  int alarms_seen = 0, moved = 0;
  for (uint32_t c = 0; c < 64; ++c) {
    ColumnContext context;
    context.column = c;
    std::vector<Measurement> a(kBeams), b(kBeams);
    without.simulate(column, context, a);
    with.simulate(column, context, b);
    for (size_t beam = 1; beam < kBeams; beam += 2) {
      ASSERT_EQ(a[beam].range_m == 0.0f, b[beam].range_m == 0.0f) << "false alarms differ at beam " << beam;
      if (a[beam].range_m == 0.0f) continue;
      ++alarms_seen;
      moved += a[beam].range_m != b[beam].range_m;
    }
  }
  EXPECT_GT(alarms_seen, 1000);
  EXPECT_EQ(moved, alarms_seen) << "the noise skipped returns added after the chain listed them";
}
