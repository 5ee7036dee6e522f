//! CPU evaluation of the lights and the BRDF, mirroring shaders/include/{lights,brdf}.glsl.
