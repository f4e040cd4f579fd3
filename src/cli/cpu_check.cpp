// The per-pixel modules may be built for x86-64-v3 (AVX2, FMA, BMI2: cmake/PixelPathIsa.cmake).
// On a CPU without those the binary would die of SIGILL somewhere in the first frame, or even in a
// static initializer; this check runs before any of them (constructor priority 101 precedes the
// default) and says what is wrong instead. This file itself is built for baseline x86-64.
#include <cstdio>
#include <cstdlib>

#if defined(LIDARTWIN_PIXEL_PATH_X86_64_V3)
namespace {
__attribute__((constructor(101))) void require_x86_64_v3() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi2")) return;
  std::fputs(
      "lidartwin: this build needs an x86-64-v3 CPU (AVX2, FMA, BMI2) and this CPU lacks one of them.\n"
      "Rebuild for any x86-64 CPU with LIDARTWIN_CMAKE_ARGS=-DLIDARTWIN_PIXEL_ISA=x86-64 tools/setup\n",
      stderr);
  std::_Exit(70);  // EX_SOFTWARE
}
}  // namespace
#endif
