// The implementations of the header-only libraries, which the native build
// links as Debian's shared libraries (libtinygltf, libstb).
#define TINYGLTF_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <tiny_gltf.h>
