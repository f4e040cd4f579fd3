#pragma once
// Reading and checking effect parameters: one table per effect lists each parameter's key, the
// field of the effect's parameter struct it fills, its bounds and whether it may be omitted (the
// struct's in-class default is then used). The same table serves JSON input, validation of
// fitted values (with_parameters) and the parameters() list, so the three cannot drift apart.
// Errors name the source, the JSON path and the allowed range (STYLE.md "Errors at the boundary").
#include <array>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect.h"
#include "lidartwin/json/json_reader.h"

namespace lidartwin::effects_detail {

using json_reader::Location;
std::string format_number(double value);
std::string format_range(double lower, double upper);  // "[0, 1]"

// Values given to with_parameters (a fit) come from no file: their messages name the effect,
// "range_noise_linear: /sigma0_m: must be in [0, 1], got -0.01".
Location fitted(std::string_view effect);

// The bounds of one key, which may be infinite (an unbounded parameter), unlike json_reader::Range.
struct Bounds {
  double lower;
  double upper;
};
double read_number(const nlohmann::json& value, const Location& at, Bounds bounds);
void check_number(double value, const Location& at, Bounds bounds);
// An object whose keys other than "name" are all in `allowed`.
void check_keys(const nlohmann::json& params, const Location& at, std::string_view effect,
                std::span<const std::string_view> allowed);
void check_count(size_t got, size_t expected, std::string_view effect);

template <class P>
struct ParameterSpec {
  std::string_view name;
  double P::*field;
  Bounds bounds;
  bool required = false;
};

template <class P, size_t N>
P read_parameters(const nlohmann::json& params, const Location& at, std::string_view effect,
                  const std::array<ParameterSpec<P>, N>& specs) {
  std::array<std::string_view, N> names;
  for (size_t i = 0; i < N; ++i) names[i] = specs[i].name;
  check_keys(params, at, effect, names);
  P p{};
  for (const auto& spec : specs) {
    const auto found = params.find(spec.name);
    if (found == params.end()) {
      if (spec.required) {
        at.child(spec.name).fail("missing; " + std::string(effect) + " needs it, a number in " +
                                 format_range(spec.bounds.lower, spec.bounds.upper));
      }
      continue;
    }
    p.*spec.field = read_number(*found, at.child(spec.name), spec.bounds);
  }
  return p;
}

template <class P, size_t N>
P from_values(std::span<const double> values, std::string_view effect, const std::array<ParameterSpec<P>, N>& specs) {
  check_count(values.size(), N, effect);
  P p{};
  for (size_t i = 0; i < N; ++i) {
    check_number(values[i], fitted(effect).child(specs[i].name), specs[i].bounds);
    p.*specs[i].field = values[i];
  }
  return p;
}

template <class P, size_t N>
std::vector<EffectParameter> describe(const P& p, const std::array<ParameterSpec<P>, N>& specs) {
  std::vector<EffectParameter> out;
  out.reserve(N);
  for (const auto& spec : specs) {
    out.push_back({std::string(spec.name), p.*spec.field, spec.bounds.lower, spec.bounds.upper, false});
  }
  return out;
}

// The shared part of an effect whose parameters are a flat table (pbrt's Shape::Create pattern):
// Derived provides kName, kSpecs, a constructor from P, and optionally
// `static void check(const P&, const Location& at)` for constraints between parameters.
template <class Derived, class P>
class TabledEffect : public Effect {
 public:
  explicit TabledEffect(const P& params) : params_(params) {}

  std::string_view name() const final { return Derived::kName; }
  std::vector<EffectParameter> parameters() const final { return describe(params_, Derived::kSpecs); }
  std::unique_ptr<Effect> with_parameters(std::span<const double> values) const final {
    auto copy = make(from_values(values, Derived::kName, Derived::kSpecs), fitted(Derived::kName));
    copy->set_stream_id(stream_id());
    return copy;
  }
  static std::unique_ptr<Effect> create(const nlohmann::json& params, const Location& at) {
    return make(read_parameters(params, at, Derived::kName, Derived::kSpecs), at);
  }
  const P& params() const { return params_; }

 private:
  static std::unique_ptr<Effect> make(const P& params, const Location& at) {
    if constexpr (requires { Derived::check(params, at); }) Derived::check(params, at);
    return std::make_unique<Derived>(params);
  }

  P params_;
};

}  // namespace lidartwin::effects_detail
