//! Every way a pass may touch a resource, as one closed enum, and the one table that maps each
//! to pipeline stage, access mask, image layout and usage flag (after Tobias Hector's
//! simple_vulkan_synchronization). Nothing else in umbra names raw stage or access flags.

use ash::vk;

/// How a pass uses a resource. Reads and writes are distinct variants, so read-after-read needs
/// no barrier and the builder can reject a read declared through `write`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Not yet touched on the device (a resource's state before its first use).
    Nothing,
    /// Written by the host through a mapping before submission (scene buffers).
    HostWrite,
    HostRead,
    VertexBuffer,
    IndexBuffer,
    VertexShaderReadUniformBuffer,
    ComputeShaderReadStorageBuffer,
    /// A uniform texel buffer read by a compute shader (`texelFetch` on a `samplerBuffer`).
    ComputeShaderReadUniformTexelBuffer,
    ComputeShaderReadUniformBuffer,
    ComputeShaderReadSampledImage,
    FragmentShaderReadSampledImage,
    /// A uniform texel buffer read by a fragment shader (the geometry pass's triangles).
    FragmentShaderReadUniformTexelBuffer,
    TransferRead,
    ComputeShaderWrite,
    ColorAttachmentWrite,
    /// Blended over what the attachment holds (loaded, not cleared): a write that also reads
    /// what came before it, so the pass that drew that is kept and ordered first (the UI).
    ColorAttachmentBlend,
    /// Depth test and write (the depth attachment of a geometry pass).
    DepthAttachmentWrite,
    /// Depth and stencil both attached and written (a combined depth-stencil image being filled).
    DepthStencilAttachmentWrite,
    /// Depth tested but not written, stencil tested and written (stencil shadow volumes counting
    /// against a depth buffer filled before).
    DepthReadStencilWrite,
    /// The depth a `DepthReadStencilWrite` pass tests against, declared by the same pass beside
    /// it (same layout), so the pass that wrote that depth is kept and ordered before it.
    DepthTestRead,
    TransferWrite,
    /// Any later read, in any stage: what data uploaded once (scene buffers) is made visible
    /// to, so frames read it with no barrier of their own.
    AnyRead,
    /// Read back by a compute shader as a storage image (read-modify-write passes).
    ComputeShaderReadStorageImage,
    /// The stencil aspect of a depth-stencil image sampled by a compute shader (a `usampler2D`):
    /// the graph binds the image's stencil-aspect view.
    ComputeShaderReadStencil,
    /// A swapchain image just acquired: contents undefined, usable once the acquire
    /// semaphore's wait (at the transfer stage, where umbra first writes it) has completed. Counted
    /// as a write so the first use orders itself after that stage.
    AcquiredImage,
    /// Handed to the presentation engine (swapchain images).
    Present,
    /// Vertex or instance data read by an acceleration-structure build.
    AccelerationStructureBuildInput,
    /// Scratch memory of an acceleration-structure build (read and written by it).
    AccelerationStructureBuildScratch,
    /// The acceleration structure a build writes (its backing buffer).
    AccelerationStructureBuildWrite,
    /// A bottom level read by the build of a top level that instances it.
    AccelerationStructureBuildRead,
    /// Ray queries from a compute shader traversing the acceleration structure.
    ComputeShaderReadAccelerationStructure,
    /// Read and written by a compute shader's atomics (an append list and its counters): a
    /// write that also reads what came before it.
    ComputeShaderAtomic,
    /// The arguments of an indirect dispatch (or draw), read by the command itself.
    IndirectCommandRead,
}

/// Which kind of resource an access applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Applies {
    Image,
    Buffer,
    Both,
}

#[derive(Clone, Copy, Debug)]
pub struct AccessInfo {
    pub stage: vk::PipelineStageFlags2,
    pub access: vk::AccessFlags2,
    pub layout: vk::ImageLayout,
    pub image_usage: vk::ImageUsageFlags,
    pub buffer_usage: vk::BufferUsageFlags,
    pub applies: Applies,
}

impl Access {
    pub fn is_write(self) -> bool {
        matches!(
            self,
            Access::HostWrite
                | Access::ComputeShaderWrite
                | Access::ColorAttachmentWrite
                | Access::ColorAttachmentBlend
                | Access::DepthAttachmentWrite
                | Access::DepthStencilAttachmentWrite
                | Access::DepthReadStencilWrite
                | Access::TransferWrite
                | Access::AcquiredImage
                | Access::AccelerationStructureBuildScratch
                | Access::AccelerationStructureBuildWrite
                | Access::ComputeShaderAtomic
        )
    }

    /// Whether the write also reads what came before it (a read-modify-write), so the pass that
    /// wrote that must be kept and ordered first, as for a read.
    pub fn reads_previous(self) -> bool {
        matches!(self, Access::ComputeShaderAtomic | Access::ColorAttachmentBlend)
    }

    /// The table. Writes contribute their access mask to a barrier's source scope; reads only
    /// their stage (an execution dependency is enough before a write-after-read).
    pub fn info(self) -> AccessInfo {
        use vk::AccessFlags2 as A;
        use vk::BufferUsageFlags as B;
        use vk::ImageLayout as L;
        use vk::ImageUsageFlags as I;
        use vk::PipelineStageFlags2 as S;
        let (stage, access, layout, image_usage, buffer_usage, applies) = match self {
            Access::Nothing => (S::NONE, A::NONE, L::UNDEFINED, I::empty(), B::empty(), Applies::Both),
            Access::HostWrite => (S::HOST, A::HOST_WRITE, L::GENERAL, I::empty(), B::empty(), Applies::Buffer),
            Access::HostRead => (S::HOST, A::HOST_READ, L::GENERAL, I::empty(), B::empty(), Applies::Buffer),
            Access::VertexBuffer => (
                S::VERTEX_ATTRIBUTE_INPUT,
                A::VERTEX_ATTRIBUTE_READ,
                L::UNDEFINED,
                I::empty(),
                B::VERTEX_BUFFER,
                Applies::Buffer,
            ),
            Access::IndexBuffer => {
                (S::INDEX_INPUT, A::INDEX_READ, L::UNDEFINED, I::empty(), B::INDEX_BUFFER, Applies::Buffer)
            }
            Access::VertexShaderReadUniformBuffer => {
                (S::VERTEX_SHADER, A::UNIFORM_READ, L::UNDEFINED, I::empty(), B::UNIFORM_BUFFER, Applies::Buffer)
            }
            Access::ComputeShaderReadStorageBuffer => (
                S::COMPUTE_SHADER,
                A::SHADER_STORAGE_READ,
                L::UNDEFINED,
                I::empty(),
                B::STORAGE_BUFFER,
                Applies::Buffer,
            ),
            Access::ComputeShaderReadUniformTexelBuffer => (
                S::COMPUTE_SHADER,
                A::SHADER_SAMPLED_READ,
                L::UNDEFINED,
                I::empty(),
                B::UNIFORM_TEXEL_BUFFER,
                Applies::Buffer,
            ),
            Access::ComputeShaderReadUniformBuffer => {
                (S::COMPUTE_SHADER, A::UNIFORM_READ, L::UNDEFINED, I::empty(), B::UNIFORM_BUFFER, Applies::Buffer)
            }
            Access::ComputeShaderReadSampledImage => (
                S::COMPUTE_SHADER,
                A::SHADER_SAMPLED_READ,
                L::SHADER_READ_ONLY_OPTIMAL,
                I::SAMPLED,
                B::empty(),
                Applies::Image,
            ),
            Access::FragmentShaderReadSampledImage => (
                S::FRAGMENT_SHADER,
                A::SHADER_SAMPLED_READ,
                L::SHADER_READ_ONLY_OPTIMAL,
                I::SAMPLED,
                B::empty(),
                Applies::Image,
            ),
            Access::FragmentShaderReadUniformTexelBuffer => (
                S::FRAGMENT_SHADER,
                A::SHADER_SAMPLED_READ,
                L::UNDEFINED,
                I::empty(),
                B::UNIFORM_TEXEL_BUFFER,
                Applies::Buffer,
            ),
            Access::TransferRead => (
                S::ALL_TRANSFER,
                A::TRANSFER_READ,
                L::TRANSFER_SRC_OPTIMAL,
                I::TRANSFER_SRC,
                B::TRANSFER_SRC,
                Applies::Both,
            ),
            Access::ComputeShaderWrite => {
                (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE, L::GENERAL, I::STORAGE, B::STORAGE_BUFFER, Applies::Both)
            }
            Access::ColorAttachmentBlend => (
                S::COLOR_ATTACHMENT_OUTPUT,
                A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE,
                L::COLOR_ATTACHMENT_OPTIMAL,
                I::COLOR_ATTACHMENT,
                B::empty(),
                Applies::Image,
            ),
            Access::ColorAttachmentWrite => (
                S::COLOR_ATTACHMENT_OUTPUT,
                A::COLOR_ATTACHMENT_WRITE,
                L::COLOR_ATTACHMENT_OPTIMAL,
                I::COLOR_ATTACHMENT,
                B::empty(),
                Applies::Image,
            ),
            Access::DepthAttachmentWrite => (
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
                L::DEPTH_ATTACHMENT_OPTIMAL,
                I::DEPTH_STENCIL_ATTACHMENT,
                B::empty(),
                Applies::Image,
            ),
            Access::DepthStencilAttachmentWrite => (
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
                L::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                I::DEPTH_STENCIL_ATTACHMENT,
                B::empty(),
                Applies::Image,
            ),
            Access::DepthReadStencilWrite => (
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
                L::DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL,
                I::DEPTH_STENCIL_ATTACHMENT,
                B::empty(),
                Applies::Image,
            ),
            Access::DepthTestRead => (
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ,
                L::DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL,
                I::DEPTH_STENCIL_ATTACHMENT,
                B::empty(),
                Applies::Image,
            ),
            Access::TransferWrite => (
                S::ALL_TRANSFER,
                A::TRANSFER_WRITE,
                L::TRANSFER_DST_OPTIMAL,
                I::TRANSFER_DST,
                B::TRANSFER_DST,
                Applies::Both,
            ),
            Access::AnyRead => (S::ALL_COMMANDS, A::MEMORY_READ, L::GENERAL, I::empty(), B::empty(), Applies::Buffer),
            Access::ComputeShaderReadStorageImage => {
                (S::COMPUTE_SHADER, A::SHADER_STORAGE_READ, L::GENERAL, I::STORAGE, B::empty(), Applies::Image)
            }
            Access::ComputeShaderReadStencil => (
                S::COMPUTE_SHADER,
                A::SHADER_SAMPLED_READ,
                L::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
                I::SAMPLED,
                B::empty(),
                Applies::Image,
            ),
            Access::AcquiredImage => (S::ALL_TRANSFER, A::NONE, L::UNDEFINED, I::empty(), B::empty(), Applies::Image),
            Access::Present => (S::NONE, A::NONE, L::PRESENT_SRC_KHR, I::empty(), B::empty(), Applies::Image),
            // Build inputs are read through device addresses, as shader reads of the build stage.
            Access::AccelerationStructureBuildInput => (
                S::ACCELERATION_STRUCTURE_BUILD_KHR,
                A::SHADER_READ,
                L::UNDEFINED,
                I::empty(),
                B::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR | B::SHADER_DEVICE_ADDRESS,
                Applies::Buffer,
            ),
            Access::AccelerationStructureBuildScratch => (
                S::ACCELERATION_STRUCTURE_BUILD_KHR,
                A::ACCELERATION_STRUCTURE_READ_KHR | A::ACCELERATION_STRUCTURE_WRITE_KHR,
                L::UNDEFINED,
                I::empty(),
                B::STORAGE_BUFFER | B::SHADER_DEVICE_ADDRESS,
                Applies::Buffer,
            ),
            Access::AccelerationStructureBuildWrite => (
                S::ACCELERATION_STRUCTURE_BUILD_KHR,
                A::ACCELERATION_STRUCTURE_WRITE_KHR,
                L::UNDEFINED,
                I::empty(),
                B::ACCELERATION_STRUCTURE_STORAGE_KHR | B::SHADER_DEVICE_ADDRESS,
                Applies::Buffer,
            ),
            Access::AccelerationStructureBuildRead => (
                S::ACCELERATION_STRUCTURE_BUILD_KHR,
                A::ACCELERATION_STRUCTURE_READ_KHR,
                L::UNDEFINED,
                I::empty(),
                B::ACCELERATION_STRUCTURE_STORAGE_KHR | B::SHADER_DEVICE_ADDRESS,
                Applies::Buffer,
            ),
            Access::ComputeShaderReadAccelerationStructure => (
                S::COMPUTE_SHADER,
                A::ACCELERATION_STRUCTURE_READ_KHR,
                L::UNDEFINED,
                I::empty(),
                B::ACCELERATION_STRUCTURE_STORAGE_KHR,
                Applies::Buffer,
            ),
            Access::ComputeShaderAtomic => (
                S::COMPUTE_SHADER,
                A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE,
                L::UNDEFINED,
                I::empty(),
                B::STORAGE_BUFFER,
                Applies::Buffer,
            ),
            Access::IndirectCommandRead => (
                S::DRAW_INDIRECT,
                A::INDIRECT_COMMAND_READ,
                L::UNDEFINED,
                I::empty(),
                B::INDIRECT_BUFFER,
                Applies::Buffer,
            ),
        };
        AccessInfo { stage, access, layout, image_usage, buffer_usage, applies }
    }

    /// Whether a descriptor for this access views the stencil aspect of a depth-stencil image
    /// (a sampled descriptor may view one aspect only).
    pub fn views_stencil(self) -> bool {
        self == Access::ComputeShaderReadStencil
    }

    pub fn applies_to_image(self) -> bool {
        self.info().applies != Applies::Buffer
    }

    pub fn applies_to_buffer(self) -> bool {
        self.info().applies != Applies::Image
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: &[Access] = &[
        Access::Nothing,
        Access::HostWrite,
        Access::HostRead,
        Access::VertexBuffer,
        Access::IndexBuffer,
        Access::VertexShaderReadUniformBuffer,
        Access::ComputeShaderReadStorageBuffer,
        Access::ComputeShaderReadUniformTexelBuffer,
        Access::ComputeShaderReadUniformBuffer,
        Access::ComputeShaderReadSampledImage,
        Access::FragmentShaderReadSampledImage,
        Access::FragmentShaderReadUniformTexelBuffer,
        Access::TransferRead,
        Access::ComputeShaderWrite,
        Access::ColorAttachmentWrite,
        Access::ColorAttachmentBlend,
        Access::DepthAttachmentWrite,
        Access::DepthStencilAttachmentWrite,
        Access::DepthReadStencilWrite,
        Access::DepthTestRead,
        Access::TransferWrite,
        Access::AnyRead,
        Access::ComputeShaderReadStorageImage,
        Access::ComputeShaderReadStencil,
        Access::AcquiredImage,
        Access::Present,
        Access::AccelerationStructureBuildInput,
        Access::AccelerationStructureBuildScratch,
        Access::AccelerationStructureBuildWrite,
        Access::AccelerationStructureBuildRead,
        Access::ComputeShaderReadAccelerationStructure,
        Access::ComputeShaderAtomic,
        Access::IndirectCommandRead,
    ];

    #[test]
    fn write_variants_carry_write_access_bits_and_reads_do_not() {
        let write_bits = vk::AccessFlags2::HOST_WRITE
            | vk::AccessFlags2::SHADER_STORAGE_WRITE
            | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE
            | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE
            | vk::AccessFlags2::TRANSFER_WRITE
            | vk::AccessFlags2::ACCELERATION_STRUCTURE_WRITE_KHR;
        for &a in ALL {
            // An acquired swapchain image is a write with no memory access of its own.
            let expected = a.info().access.intersects(write_bits) || a == Access::AcquiredImage;
            assert_eq!(a.is_write(), expected, "{a:?}");
        }
    }

    #[test]
    fn image_accesses_name_a_layout_and_buffer_only_ones_do_not_need_one() {
        for &a in ALL {
            let info = a.info();
            if info.applies == Applies::Image && a != Access::Nothing && a != Access::AcquiredImage {
                assert_ne!(info.layout, vk::ImageLayout::UNDEFINED, "{a:?}");
            }
        }
    }
}
