# Module boundaries (DESIGN.md "Modules"): a module may include the public headers of the modules
# it depends on (module_deps_* in src/CMakeLists.txt, transitively) and the third-party libraries it
# names (module_third_party_*), plus what those modules' public headers bring along. Linking alone
# cannot enforce that: every Debian library's headers sit in /usr/include and every module header in
# include/, where any target finds them, and a static library's missing symbols only surface in the
# final link, which has everything. So each module gets, ahead of the real include paths, folders of
# stand-in headers that stop the compile with an #error for everything outside its reach.

# Third-party libraries by the short names the module lists use. TARGETS: what a user links.
# HEADERS: the library's entry headers (each gets an #error stand-in where the library is out of
# reach); a header a library includes from its own folder with quotes bypasses stand-ins, so list
# those the library's other headers all pass through (asio/detail/config.hpp). IMPLIES: libraries
# its headers include themselves, allowed along with it. Eigen needs no stand-ins: its headers are
# outside the default include path, so a module that does not link it cannot find them.
function(lidartwin_third_party name)
  cmake_parse_arguments(PARSE_ARGV 1 arg "" "" "TARGETS;HEADERS;IMPLIES")
  set_property(GLOBAL APPEND PROPERTY lidartwin_third_party_names ${name})
  set_property(GLOBAL PROPERTY lidartwin_third_party_targets_${name} ${arg_TARGETS})
  set_property(GLOBAL PROPERTY lidartwin_third_party_implies_${name} ${arg_IMPLIES})
  foreach(header ${arg_HEADERS})
    file(CONFIGURE OUTPUT ${CMAKE_BINARY_DIR}/module_boundaries/third_party/${name}/${header} CONTENT
         "#error \"<${header}> is ${name}, which this module does not use: add it to the module's module_third_party_* list in src/CMakeLists.txt if DESIGN.md allows\"\n")
  endforeach()
endfunction()

# Tinygltf's header is built here without its image loaders (we load no textures).
add_library(lidartwin_tinygltf INTERFACE)
target_link_libraries(lidartwin_tinygltf INTERFACE TinyGLTF::TinyGLTF)
target_compile_definitions(lidartwin_tinygltf INTERFACE TINYGLTF_NO_STB_IMAGE TINYGLTF_NO_STB_IMAGE_WRITE)

lidartwin_third_party(sockets HEADERS sys/socket.h netinet/in.h arpa/inet.h netdb.h)  # POSIX, in libc
lidartwin_third_party(asio TARGETS lidartwin_asio HEADERS asio.hpp asio/detail/config.hpp IMPLIES sockets)
lidartwin_third_party(httplib TARGETS PkgConfig::HTTPLIB HEADERS httplib.h IMPLIES sockets)
lidartwin_third_party(pcap TARGETS PkgConfig::PCAP HEADERS pcap.h pcap/pcap.h IMPLIES sockets)
lidartwin_third_party(embree TARGETS embree HEADERS embree3/rtcore.h)
lidartwin_third_party(flatbuffers TARGETS flatbuffers::flatbuffers HEADERS flatbuffers/flatbuffers.h)
lidartwin_third_party(stb TARGETS PkgConfig::STB HEADERS stb_image.h stb/stb_image.h)
lidartwin_third_party(zstd TARGETS PkgConfig::ZSTD HEADERS zstd.h)
lidartwin_third_party(tinygltf TARGETS lidartwin_tinygltf HEADERS tiny_gltf.h)
lidartwin_third_party(nlopt TARGETS NLopt::nlopt HEADERS nlopt.h nlopt.hpp)
lidartwin_third_party(lzma TARGETS LibLZMA::LibLZMA HEADERS lzma.h)
lidartwin_third_party(nlohmann_json TARGETS nlohmann_json::nlohmann_json HEADERS nlohmann/json.hpp
                      nlohmann/json_fwd.hpp)
lidartwin_third_party(fmt TARGETS fmt::fmt HEADERS fmt/core.h fmt/format.h fmt/ranges.h fmt/chrono.h fmt/ostream.h)
lidartwin_third_party(spdlog TARGETS spdlog::spdlog HEADERS spdlog/spdlog.h spdlog/common.h spdlog/tweakme.h
                      IMPLIES fmt)
lidartwin_third_party(eigen TARGETS Eigen3::Eigen)
lidartwin_third_party(cli11 TARGETS CLI11::CLI11 HEADERS CLI/CLI.hpp)
lidartwin_third_party(threads TARGETS Threads::Threads)
lidartwin_third_party(hwy TARGETS hwy::hwy HEADERS hwy/highway.h hwy/foreach_target.h hwy/base.h hwy/targets.h)

# Links `target` PRIVATE to the named libraries, unfenced (tests, tools).
function(lidartwin_link_third_party target)
  get_property(known GLOBAL PROPERTY lidartwin_third_party_names)
  foreach(name ${ARGN})
    if(NOT name IN_LIST known)
      message(FATAL_ERROR "${target}: unknown third-party library '${name}' (known: ${known}; cmake/ModuleBoundaries.cmake)")
    endif()
    get_property(targets GLOBAL PROPERTY lidartwin_third_party_targets_${name})
    target_link_libraries(${target} PRIVATE ${targets})
  endforeach()
endfunction()

# Stand-ins for the modules' public headers (include/lidartwin/<module>/), for the targets that do
# not depend on them.
function(lidartwin_module_stand_ins)
  foreach(module ${ARGN})
    file(GLOB_RECURSE headers CONFIGURE_DEPENDS RELATIVE ${PROJECT_SOURCE_DIR}/include
         ${PROJECT_SOURCE_DIR}/include/lidartwin/${module}/*.h)
    foreach(header ${headers})
      file(CONFIGURE OUTPUT ${CMAKE_BINARY_DIR}/module_boundaries/module/${module}/${header} CONTENT
           "#error \"${header} is module ${module}, which this module does not depend on: see its module_deps_* list in src/CMakeLists.txt and DESIGN.md's module table\"\n")
    endforeach()
  endforeach()
endfunction()

# Links `target` to the third-party libraries named in `uses` ("PUBLIC a b PRIVATE c", scopes as in
# target_link_libraries; INTERFACE for header-only targets) and fences it: every library not reached
# through `uses` or `inherited` (names that modules it depends on expose publicly), and every module
# not in `modules` (the module itself and everything it depends on), becomes an #error stand-in.
# Sets <out_public> to the names this target exposes publicly, for the targets above it.
function(lidartwin_fence target modules inherited uses out_public)
  set(scope PRIVATE)
  set(reached ${inherited})
  set(public ${inherited})
  foreach(item ${uses})
    if(item MATCHES "^(PUBLIC|PRIVATE|INTERFACE)$")
      set(scope ${item})
      continue()
    endif()
    get_property(known GLOBAL PROPERTY lidartwin_third_party_names)
    if(NOT item IN_LIST known)
      message(FATAL_ERROR "${target}: unknown third-party library '${item}' (known: ${known}; cmake/ModuleBoundaries.cmake)")
    endif()
    get_property(targets GLOBAL PROPERTY lidartwin_third_party_targets_${item})
    target_link_libraries(${target} ${scope} ${targets})
    list(APPEND reached ${item})
    if(NOT scope STREQUAL "PRIVATE")
      list(APPEND public ${item})
    endif()
  endforeach()
  # What a reached library's own headers include is reached too.
  set(pending ${reached})
  while(pending)
    list(POP_FRONT pending name)
    get_property(implied GLOBAL PROPERTY lidartwin_third_party_implies_${name})
    foreach(other ${implied})
      if(NOT other IN_LIST reached)
        list(APPEND reached ${other})
        list(APPEND pending ${other})
      endif()
    endforeach()
  endwhile()

  get_target_property(type ${target} TYPE)
  if(NOT type STREQUAL "INTERFACE_LIBRARY")  # stand-ins matter only where something is compiled
    set(fences "")
    get_property(names GLOBAL PROPERTY lidartwin_third_party_names)
    foreach(name ${names})
      if(NOT name IN_LIST reached AND IS_DIRECTORY ${CMAKE_BINARY_DIR}/module_boundaries/third_party/${name})
        list(APPEND fences ${CMAKE_BINARY_DIR}/module_boundaries/third_party/${name})
      endif()
    endforeach()
    foreach(module ${LIDARTWIN_MODULES})
      set(dir ${CMAKE_BINARY_DIR}/module_boundaries/module/${module})
      if(NOT module IN_LIST modules AND IS_DIRECTORY ${dir})
        list(APPEND fences ${dir})
      endif()
    endforeach()
    target_include_directories(${target} BEFORE PRIVATE ${fences})
  endif()
  list(REMOVE_DUPLICATES public)
  set(${out_public} ${public} PARENT_SCOPE)
endfunction()
