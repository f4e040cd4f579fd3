#pragma once
// The expectations over E6's echoes (Prediction::echoes) that the effects reading the signal take
// in predict, where their simulate reads each pixel's own draw of it.
#include <cstddef>

#include "lidartwin/effects/measurement.h"

namespace lidartwin::effects_detail {

// The weighted means of value(signal) over the pixel's own echoes and over its partner's; a side
// without weight (none of its echoes detected) takes the other's, and a pixel without echoes (or
// with none detected) the value of its mean signal, so the result is always some echo's value.
struct EchoMeans {
  double own = 0.0;
  double partner = 0.0;
};

template <class F>
EchoMeans echo_means(const Prediction& p, F value) {
  double own = 0.0, partner = 0.0, own_weight = 0.0, partner_weight = 0.0;
  for (size_t k = 0; k < p.echo_count; ++k) {
    const Prediction::Echo& e = p.echoes[k];
    const double w = e.weight;
    if (w <= 0.0) continue;
    const double v = value(p.signal_photons * static_cast<double>(e.signal_factor));
    (k < p.own_echoes ? own : partner) += w * v;
    (k < p.own_echoes ? own_weight : partner_weight) += w;
  }
  if (own_weight <= 0.0 && partner_weight <= 0.0) {
    const double v = value(p.signal_photons);
    return {v, v};
  }
  own = own_weight > 0.0 ? own / own_weight : partner / partner_weight;
  partner = partner_weight > 0.0 ? partner / partner_weight : own;
  return {own, partner};
}

// The mean and variance of the own echoes' range offsets (a merged echo's, E6).
struct OffsetMoments {
  double mean = 0.0;
  double variance = 0.0;
};
inline OffsetMoments own_offset_moments(const Prediction& p) {
  double w = 0.0, m1 = 0.0, m2 = 0.0;
  for (size_t k = 0; k < p.own_echoes; ++k) {
    const Prediction::Echo& e = p.echoes[k];
    const double weight = e.weight, x = e.offset_m;
    w += weight, m1 += weight * x, m2 += weight * x * x;
  }
  if (w <= 0.0) return {};
  m1 /= w;
  const double variance = m2 / w - m1 * m1;
  return {m1, variance > 0.0 ? variance : 0.0};
}

// Weighs each echo by the probability that it is detected (dropout): the pixel's detection is
// their sum, and the partner's share, the echoes' weights and a merged echo's mean and spread
// become those of the echoes detected.
template <class F>
void detect_echoes(Prediction& p, F probability) {
  const OffsetMoments moments_before = own_offset_moments(p);
  double prior = 0.0, total = 0.0, partner = 0.0;
  for (size_t k = 0; k < p.echo_count; ++k) {
    Prediction::Echo& e = p.echoes[k];
    const double before = e.weight;
    const double after = before * probability(p.signal_photons * static_cast<double>(e.signal_factor));
    e.weight = static_cast<float>(after);
    prior += before;
    total += after;
    if (k >= p.own_echoes) partner += after;
  }
  if (prior <= 0.0) return;
  p.p_detect *= total / prior;
  if (total <= 0.0) return;  // nothing is detected: the shares no longer matter
  for (size_t k = 0; k < p.echo_count; ++k) {
    p.echoes[k].weight = static_cast<float>(static_cast<double>(p.echoes[k].weight) / total);
  }
  if (p.echo_count > p.own_echoes) p.partner_mix = partner / total;
  const OffsetMoments moments_after = own_offset_moments(p);
  p.bias_m += moments_after.mean - moments_before.mean;
  p.variance_m2 += moments_after.variance - moments_before.variance;
}

}  // namespace lidartwin::effects_detail
