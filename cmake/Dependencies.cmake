# Every dependency is a Debian bookworm package; tools/setup installs them.
find_package(Threads REQUIRED)
find_package(embree 3 REQUIRED)
find_package(TinyGLTF REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(spdlog REQUIRED)
find_package(Eigen3 REQUIRED NO_MODULE)
find_package(CLI11 REQUIRED)
find_package(NLopt REQUIRED)
find_package(GTest REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(PCAP REQUIRED IMPORTED_TARGET libpcap)
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
# OSF recordings: flatbuffers (header-only use) for their tables, stb_image for their PNG fields,
# zstd for their ZPNG fields (ouster-cli's default encoding in ouster-sdk 1.0.1).
find_package(FlatBuffers REQUIRED)
pkg_check_modules(STB REQUIRED IMPORTED_TARGET stb)
pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)
if(LIDARTWIN_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()
# Standalone Asio is header-only (libasio-dev): /usr/include/asio.hpp.
find_path(ASIO_INCLUDE_DIR asio.hpp REQUIRED)
add_library(lidartwin_asio INTERFACE)
target_include_directories(lidartwin_asio SYSTEM INTERFACE ${ASIO_INCLUDE_DIR})
target_compile_definitions(lidartwin_asio INTERFACE ASIO_STANDALONE ASIO_NO_DEPRECATED)
find_package(fmt REQUIRED)  # also spdlog's formatter
find_package(LibLZMA REQUIRED)  # lzma_crc64: the packets' CRC-64/XZ
# Google Highway (libhwy-dev): SIMD kernels compiled once per target, the CPU's best chosen at run
# time (cmake/InstructionSet.cmake).
find_package(hwy REQUIRED)
