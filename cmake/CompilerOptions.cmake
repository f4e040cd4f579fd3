# Strict warnings for every target of ours (not for third-party headers: they are SYSTEM).
add_library(lidartwin_warnings INTERFACE)
target_compile_options(lidartwin_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align
  -Wunused -Woverloaded-virtual -Wdouble-promotion -Wformat=2
  -Wimplicit-fallthrough)
# GCC 12 at -O3 reports false -Wrestrict overlaps inside std::string's operator+ (GCC bug 105329),
# which breaks Release builds with warnings as errors.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  target_compile_options(lidartwin_warnings INTERFACE -Wno-restrict)
endif()
if(LIDARTWIN_WERROR)
  target_compile_options(lidartwin_warnings INTERFACE -Werror)
  # Clang (the fuzzing build) also flags float -> double in initializers, which GCC leaves alone
  # and the code does on purpose (float channels into double arithmetic): shown, not fatal.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    target_compile_options(lidartwin_warnings INTERFACE -Wno-error=double-promotion)
  endif()
endif()

if(LIDARTWIN_SANITIZE AND LIDARTWIN_TSAN)
  message(FATAL_ERROR "LIDARTWIN_SANITIZE and LIDARTWIN_TSAN exclude each other: use two build directories")
endif()
if(LIDARTWIN_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
  add_link_options(-fsanitize=address,undefined)
endif()
if(LIDARTWIN_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "LIDARTWIN_FUZZ needs clang (libFuzzer): CXX=clang++, got ${CMAKE_CXX_COMPILER_ID}")
  endif()
  # Coverage for libFuzzer in every module a target links; the targets add the fuzzer's main.
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()
if(LIDARTWIN_TSAN)
  # -O1 (TSan's recommendation) and line tables: the TSan build compiles most modules again in
  # tools/test, and its reports need only file:line.
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer -O1 -g1)
  add_link_options(-fsanitize=thread)
  # GCC 12 warns that TSan does not model std::atomic_thread_fence, which Asio's handler
  # completions use; the io_context queues handlers under a mutex, which TSan does see.
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_GREATER_EQUAL 12)
    add_compile_options(-Wno-tsan)
  endif()
endif()
