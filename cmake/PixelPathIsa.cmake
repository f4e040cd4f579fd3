# The instruction set of the per-pixel modules (packet, caster, effects, frame). Their loops are
# written to vectorize; with AVX2 and FMA (x86-64-v3) they process twice the lanes of baseline
# x86-64, which pipeline_bench measures as part of the pipeline's speed against raw Embree
# (Embree itself picks AVX2/AVX-512 at run time). The rest of the program stays baseline, and the
# binary checks at start that the CPU has what these modules were built for (cli/main.cpp).
#   auto       x86-64-v3 when the build machine has AVX2, FMA and BMI2, else baseline (default)
#   x86-64-v3  always (the binary then needs a 2013-or-later x86 CPU: Haswell, Zen)
#   x86-64     baseline: a binary for any x86-64 CPU, e.g. an image for unknown machines
set(LIDARTWIN_PIXEL_ISA "auto" CACHE STRING "ISA level of the per-pixel modules: auto, x86-64-v3 or x86-64")
set_property(CACHE LIDARTWIN_PIXEL_ISA PROPERTY STRINGS auto x86-64-v3 x86-64)

set(LIDARTWIN_PIXEL_ISA_FLAGS "")
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  if(LIDARTWIN_PIXEL_ISA STREQUAL "auto")
    include(CheckCXXSourceRuns)
    check_cxx_source_runs("
      int main() {
        __builtin_cpu_init();
        return __builtin_cpu_supports(\"avx2\") && __builtin_cpu_supports(\"fma\") &&
               __builtin_cpu_supports(\"bmi2\") ? 0 : 1;
      }" LIDARTWIN_BUILD_HOST_HAS_X86_64_V3)
    if(LIDARTWIN_BUILD_HOST_HAS_X86_64_V3)
      set(LIDARTWIN_PIXEL_ISA_FLAGS -march=x86-64-v3)
    endif()
  elseif(LIDARTWIN_PIXEL_ISA STREQUAL "x86-64-v3")
    set(LIDARTWIN_PIXEL_ISA_FLAGS -march=x86-64-v3)
  elseif(NOT LIDARTWIN_PIXEL_ISA STREQUAL "x86-64")
    message(FATAL_ERROR "LIDARTWIN_PIXEL_ISA must be auto, x86-64-v3 or x86-64, got '${LIDARTWIN_PIXEL_ISA}'")
  endif()
elseif(NOT LIDARTWIN_PIXEL_ISA STREQUAL "auto")
  message(FATAL_ERROR "LIDARTWIN_PIXEL_ISA applies to x86-64 only; this is ${CMAKE_SYSTEM_PROCESSOR}")
endif()
message(STATUS "lidartwin: per-pixel modules built for ${LIDARTWIN_PIXEL_ISA_FLAGS} (LIDARTWIN_PIXEL_ISA=${LIDARTWIN_PIXEL_ISA})")
