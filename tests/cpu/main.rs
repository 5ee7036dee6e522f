//! Tests that need no Vulkan device: parsers, the BVH on the CPU, the frame graph's plans,
//! the CPU twins of the shaders, the bench's metrics.
//!
//! One test binary (one link of umbra) whose modules share `common`. The suite has three:
//! `cpu`, `gpu` and `viewer`; `cargo test --release --test gpu stress_scenes::` runs one module.

#[path = "../common/mod.rs"]
mod common;
#[path = "../gltf_builder/mod.rs"]
mod gltf_builder;

mod animation;
mod bench_metrics;
mod bvh_cpu;
mod cap_cubature;
mod file_references;
mod forest_asset;
mod gltf_checks;
mod graph_layers;
mod graph_plan;
mod imports;
mod kept_instances;
mod ltc;
mod mesh_formats;
mod models;
mod parser_mutation;
mod refit_traversal;
mod scene_files;
mod shading_cpu;
mod skinning;
mod stress_assets;
