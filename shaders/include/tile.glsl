// The pixel of a full-screen compute invocation (workgroups of passes::TILE, specialisation
// constants 0 and 1). The includer enables GL_KHR_shader_subgroup_basic.
//
// It is gl_GlobalInvocationID.xy, but lavapipe derives the local invocation ID from each
// invocation's flat index with integer divisions by a workgroup size it takes at run time: two
// scalar divides per invocation, a third of accumulate's time and a fifth of compose's at
// 1920x1080. Where whole subgroups fill each row of the workgroup (TILE_BY_SUBGROUPS, set by
// ComputePipeline::new from the device's largest subgroup size), the flat index is rebuilt from
// the subgroup's instead (the Vulkan specification's own formula for whole subgroups), and the
// divisions are by the constant workgroup size: shifts. Either way each pixel of the workgroup's
// tile gets one invocation.
#ifndef UMBRA_TILE_GLSL
#define UMBRA_TILE_GLSL

layout(constant_id = 2) const bool TILE_BY_SUBGROUPS = false;

uvec2 tile_pixel() {
    if (TILE_BY_SUBGROUPS) {
        uint index = gl_SubgroupID * gl_SubgroupSize + gl_SubgroupInvocationID;
        uvec2 local = uvec2(index % gl_WorkGroupSize.x, index / gl_WorkGroupSize.x);
        return gl_WorkGroupID.xy * gl_WorkGroupSize.xy + local;
    }
    return gl_GlobalInvocationID.xy;
}

#endif
