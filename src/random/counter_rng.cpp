// RandomStream is header-only (it runs per pixel); this unit checks the header compiles alone.
#include "lidartwin/random/counter_rng.h"

namespace lidartwin {
static_assert(RandomStream(1, PixelKey{2, 3, 4}, 5).bits(0) != RandomStream(1, PixelKey{2, 3, 4}, 6).bits(0),
              "effects must get different streams");
}  // namespace lidartwin
