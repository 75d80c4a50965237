// Strata GL: the OpenGL 4.5 core entry points (glad loader, committed in
// third_party/glad).  Include this instead of any other GL header.
#pragma once

#include <glad/gl.h>
