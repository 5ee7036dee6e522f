//! Tests that render on lavapipe, in this process or through the umbra binary, with validation
//! and synchronization validation on: any message fails.
//!
//! One test binary (one link of umbra) whose modules share `common`. The suite has three:
//! `cpu`, `gpu` and `viewer`; `cargo test --release --test gpu stress_scenes::` runs one module.

#[path = "../common/mod.rs"]
mod common;
#[path = "../gltf_builder/mod.rs"]
mod gltf_builder;

mod alpha_masked_shadows;
mod ambient_occlusion;
mod antialiasing;
mod area_lights;
mod auto;
mod bench_rays;
mod bench_shadows;
mod bvh_gpu;
mod cli;
mod data_uris;
mod deforming;
mod denoise;
mod denoise_kinds;
mod depth;
mod devices;
mod double_sided;
mod environment;
mod environment_map;
mod evsm;
mod far_from_origin;
mod gltf_scenes;
mod hybrid;
mod instancing;
mod large_scene;
mod light_sampling_gpu;
mod lighting_with_textures;
mod many_lights;
mod motion_vectors;
mod moving_scenes;
mod ray_query;
mod ray_query_moving;
mod rect_lights;
mod rect_shadows;
mod refit_leaves;
mod render_accuracy;
mod samplers;
mod shadow_choice;
mod shadow_map;
mod shadow_map_kinds;
mod shadow_volumes;
mod skinning;
mod soft_shadows;
mod stress_scenes;
mod sync_validation;
mod technique_matrix;
mod terminator;
mod texture_transform;
mod textures;
mod timings;
mod trace_variants;
mod traced_tiles;
mod transient_cache;
mod two_level_bvh;
mod upload;
