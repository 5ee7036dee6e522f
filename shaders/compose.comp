#version 460
// Compose with ray-traced visibility.
#define WITH_VISIBILITY
#include "compose_body.glsl"
