// libFuzzer: a glTF or glb scene (serve/record --scene FILE) through Scene::load, the one entry the
// daemon and the tools use: tinygltf's parser, the node walk, accessors, materials and Embree's
// build. Loaded or refused with an InputError; nothing else escapes. Scene::load takes a path
// (ASCII glTF resolves its buffer URIs next to the file), so each input is written to a file in a
// private temporary directory first. Seeds: the shipped scenes and a small ASCII glTF (tools/fuzz).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "lidartwin/error.h"
#include "lidartwin/scene/scene.h"

namespace {

// Made on first use, removed when the fuzzer exits.
struct TemporaryDirectory {
  std::filesystem::path path;
  TemporaryDirectory() {
    std::string pattern = (std::filesystem::temp_directory_path() / "gltf_scene_fuzz.XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) std::abort();
    path = pattern;
  }
  ~TemporaryDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
};

std::filesystem::path input_path() {
  static const TemporaryDirectory directory;
  return directory.path / "input.gltf";
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path path = input_path();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) std::abort();
  }
  try {
    const lidartwin::Scene scene = lidartwin::Scene::load(path);
    if (scene.triangle_count() == 0) std::abort();  // load() promises triangles or an error
  } catch (const lidartwin::InputError&) {
  }
  return 0;
}
