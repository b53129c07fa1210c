#pragma once
// OpenGL 3.3 core declarations. libOpenGL (glvnd) exports every core entry
// point, so no loader is needed: prototypes come straight from glcorearb.h.
#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
