# One instruction set for every translation unit: the compiler's default (baseline x86-64 with
# Debian's GCC, ARMv8-A on arm64), so one binary or image runs on any CPU of its architecture.
# No module gets its own -march: the per-pixel loops that want wider SIMD are Highway kernels
# (src/*/*_kernels.cpp), compiled once per target (SSSE3, SSE4, AVX2, AVX-512; NEON and SVE on
# arm64) inside that target's function attributes, the CPU's best chosen at run time.
# tests/simd_targets_test.cpp records the same captures under each target and compares the bytes.
#
# Why not some modules for x86-64-v3, as before: Eigen aligns its fixed-size types to the widest
# vector the translation unit may use (Quaterniond to 32 bytes with AVX, 16 without), so Pose and
# everything holding one had two layouts in one program, and inline functions compiled with AVX
# could be the copy the linker kept for baseline callers.
#
# EIGEN_MAX_STATIC_ALIGN_BYTES pins that alignment to 16 even where AVX is on (a Highway target's
# region, or someone's -march=native): the pose types' layout is then the one asserted in
# include/lidartwin/pose/pose.h whatever a translation unit is compiled for.
add_compile_definitions(EIGEN_MAX_STATIC_ALIGN_BYTES=16)
# A multiply and an add stay two roundings on targets that have fused multiply-add (Highway's
# AVX2 and AVX-512 regions, every arm64 CPU): the same seed gives the same bytes on every CPU.
add_compile_options(-ffp-contract=off)
