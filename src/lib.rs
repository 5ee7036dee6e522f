//! umbra: an explicit Vulkan renderer whose shadows are ray traced in a compute pass over a
//! CPU-built BVH, so it runs on any Vulkan 1.3 device, software rasterisers included.

pub mod bench;
pub mod config;
pub mod diagnostics;
pub mod frame;
pub mod gpu;
pub mod graph;
pub mod lighting;
pub mod maths;
pub mod output;
pub mod passes;
pub mod renderer;
pub mod scene;
pub mod shading;
pub mod shadows;
pub mod timing;
pub mod viewer;
pub mod vk;
