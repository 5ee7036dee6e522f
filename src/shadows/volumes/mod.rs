//! Stencil shadow volumes (z-fail, with z-pass kept for comparison). So far: the device-free
//! adjacency and manifold check that decides which casters qualify.

pub mod adjacency;
