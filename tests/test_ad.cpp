#include <evnerf/ad/expr.hpp>

#include "common.hpp"

using namespace evnerf;

TEST_CASE("ad: every operation's generated gradient matches finite differences") {
  auto f = [](auto a, auto b, auto c) {
    using ad::exp, ad::log, ad::sqrt, ad::relu, ad::sigmoid, ad::softplus, ad::square, ad::sin, ad::cos;
    return exp(a * b) / (2.0 + square(c)) + log(1.5 + sigmoid(a - c)) - sqrt(3.0 + b * b) * softplus(c) + relu(a + 0.3) * sin(b) +
           cos(c) * ad::max(a, b) - ad::min(b, c) * 0.7 - (-a);
  };
  for (const std::array<double, 3> x : {std::array<double, 3>{0.3, -0.7, 1.1}, {-0.2, 0.9, -0.4}, {1.3, 0.1, 0.6}}) {
    CAPTURE(x[0]);
    auto vg = ad::value_and_grad([&](auto a, auto b, auto c) { return f(a, b, c); }, x);
    CHECK(vg.value == doctest::Approx(f(x[0], x[1], x[2])).epsilon(1e-12));
    auto plain = [&](const std::vector<double>& v) { return f(v[0], v[1], v[2]); };
    CHECK(evtest::max_fd_error(plain, {x[0], x[1], x[2]}, {vg.grad[0], vg.grad[1], vg.grad[2]}) < 1e-7);
  }
}

TEST_CASE("ad: shared subexpressions accumulate adjoints along every path") {
  auto vg = ad::value_and_grad([](auto x) { return x * x * x; }, std::array<double, 1>{2.0});
  CHECK(vg.value == doctest::Approx(8.0));
  CHECK(vg.grad[0] == doctest::Approx(12.0));
}

TEST_CASE("ad: the same text on plain scalars computes values only") {
  auto f = [](auto a, auto b) { return ad::relu(a - b) + ad::exp(b); };
  static_assert(std::is_same_v<decltype(ad::value(f, 1.0f, 2.0f)), float>);
  CHECK(ad::value(f, 3.0f, 1.0f) == doctest::Approx(2.0f + std::exp(1.0f)));
  // A function that ignores its arguments has zero gradient.
  auto vg = ad::value_and_grad([](auto) { return 4.0; }, std::array<double, 1>{1.0});
  CHECK(vg.value == 4.0);
  CHECK(vg.grad[0] == 0.0);
}
