# One instruction set for every translation unit: the compiler's default (baseline x86-64 with
# Debian's GCC, ARMv8-A on arm64), so one binary or image runs on any CPU of its architecture.
# No module gets its own -march: per-pixel loops that want wider SIMD must pick it at run time
# (DESIGN.md: Highway's dynamic dispatch), each target compiled inside its own function attributes.
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
