//! Shadow-caster BVH: built with obvhs on the CPU, flattened to the layout the GPU traverses.
