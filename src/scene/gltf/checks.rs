//! Checks of a glTF file's accessors and primitive attributes before the crate's reader sees
//! them: it would give up silently, overflow or panic on what these refuse.

/// Refuses an accessor whose elements (or sparse indices and values) do not all lie inside
/// their buffer view, a view outside its buffer, or a byteStride shorter than an element: the
/// crate's reader would give up silently there, overflow on a count of 0, or panic.
pub(super) fn check_accessor(accessor: &gltf::Accessor, buffers: &[gltf::buffer::Data]) -> Result<(), String> {
    let index = accessor.index();
    let element = accessor.size();
    let count = accessor.count();
    if count == 0 {
        return Err(format!("accessor {index} has no elements"));
    }
    // Without a view the elements are zeros (then replaced by sparse values, if any).
    if let Some(view) = accessor.view() {
        check_elements(&format!("accessor {index}"), &view, accessor.offset(), count, element, buffers)?;
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(format!("accessor {index} replaces {n} sparse elements, not 1 to its {count}"));
        }
        let (indices, values) = (sparse.indices(), sparse.values());
        let size = indices.index_type().size();
        check_elements(
            &format!("accessor {index}'s sparse indices"),
            &indices.view(),
            indices.offset(),
            n,
            size,
            buffers,
        )?;
        check_elements(
            &format!("accessor {index}'s sparse values"),
            &values.view(),
            values.offset(),
            n,
            element,
            buffers,
        )?;
        // The crate's reader skips an index past the accessor's end without a word.
        let view = indices.view();
        let bytes = &buffers[view.buffer().index()][view.offset()..view.offset() + view.length()];
        let stride = view.stride().unwrap_or(size);
        for k in 0..n {
            let at = indices.offset() + k * stride;
            let sparse_index = match indices.index_type() {
                gltf::accessor::sparse::IndexType::U8 => u64::from(bytes[at]),
                gltf::accessor::sparse::IndexType::U16 => u64::from(u16::from_le_bytes([bytes[at], bytes[at + 1]])),
                gltf::accessor::sparse::IndexType::U32 => {
                    u64::from(u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]))
                }
            };
            if sparse_index >= count as u64 {
                return Err(format!(
                    "accessor {index}'s sparse index {sparse_index} (entry {k}) is out of range: the accessor has {count} elements"
                ));
            }
        }
    }
    Ok(())
}

/// Refuses `count` elements of `element` bytes from `offset` in `view` (`what` names them)
/// that do not all lie inside it, a view outside its buffer, or a stride shorter than an element.
fn check_elements(
    what: &str,
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    element: usize,
    buffers: &[gltf::buffer::Data],
) -> Result<(), String> {
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(format!(
            "{what} has elements of {element} bytes, but buffer view {} strides {stride} bytes",
            view.index()
        ));
    }
    let end = (count - 1).checked_mul(stride).and_then(|e| e.checked_add(element)).and_then(|e| e.checked_add(offset));
    if end.is_none_or(|end| end > view.length()) {
        return Err(format!(
            "{what} reads {count} elements of {element} bytes past the end of buffer view {} ({} bytes)",
            view.index(),
            view.length()
        ));
    }
    let buffer = view.buffer().index();
    let have = buffers.get(buffer).map_or(0, |b| b.len());
    if view.offset().checked_add(view.length()).is_none_or(|end| end > have) {
        return Err(format!("buffer view {} reaches past the end of buffer {buffer} ({have} bytes)", view.index()));
    }
    Ok(())
}

/// Refuses a primitive attribute umbra reads, or its indices, whose accessor has a type glTF
/// does not allow there: the crate's reader panics on some (float indices, u32 texture
/// coordinates) and reads others as what they are not (u8 positions as floats).
pub(super) fn check_attribute_types(primitive: &gltf::Primitive) -> Result<(), String> {
    use gltf::accessor::{DataType, Dimensions};
    use gltf::mesh::Semantic;
    let describe = |accessor: &gltf::Accessor| {
        let dimensions = match accessor.dimensions() {
            Dimensions::Scalar => "SCALAR",
            Dimensions::Vec2 => "VEC2",
            Dimensions::Vec3 => "VEC3",
            Dimensions::Vec4 => "VEC4",
            Dimensions::Mat2 => "MAT2",
            Dimensions::Mat3 => "MAT3",
            Dimensions::Mat4 => "MAT4",
        };
        let normalized = if accessor.normalized() { "normalized " } else { "" };
        format!("{dimensions} of {normalized}{}", format!("{:?}", accessor.data_type()).to_lowercase())
    };
    let attributes =
        primitive.attributes().map(|(semantic, accessor)| (semantic.to_string(), Some(semantic), accessor));
    let indices = primitive.indices().map(|accessor| ("indices".to_owned(), None, accessor));
    for (name, semantic, accessor) in attributes.chain(indices) {
        let (dimensions, data_type) = (accessor.dimensions(), accessor.data_type());
        let (ok, expected) = match semantic {
            Some(Semantic::Positions | Semantic::Normals) => {
                (dimensions == Dimensions::Vec3 && data_type == DataType::F32, "VEC3 of f32")
            }
            Some(Semantic::Tangents) => (dimensions == Dimensions::Vec4 && data_type == DataType::F32, "VEC4 of f32"),
            Some(Semantic::TexCoords(_)) => {
                let unorm = accessor.normalized() && matches!(data_type, DataType::U8 | DataType::U16);
                (
                    dimensions == Dimensions::Vec2 && (data_type == DataType::F32 || unorm),
                    "VEC2 of f32, or of normalized u8 or u16",
                )
            }
            Some(Semantic::Joints(_)) => (
                dimensions == Dimensions::Vec4 && matches!(data_type, DataType::U8 | DataType::U16),
                "VEC4 of u8 or u16",
            ),
            Some(Semantic::Weights(_)) => {
                let unorm = accessor.normalized() && matches!(data_type, DataType::U8 | DataType::U16);
                (
                    dimensions == Dimensions::Vec4 && (data_type == DataType::F32 || unorm),
                    "VEC4 of f32, or of normalized u8 or u16",
                )
            }
            Some(_) => (true, ""), // not read
            None => {
                let unsigned = matches!(data_type, DataType::U8 | DataType::U16 | DataType::U32);
                (dimensions == Dimensions::Scalar && unsigned, "SCALAR of u8, u16 or u32")
            }
        };
        if !ok {
            let index = accessor.index();
            return Err(format!(
                "{name} accessor {index} is {}; glTF allows only {expected} there",
                describe(&accessor)
            ));
        }
    }
    Ok(())
}

/// Refuses a primitive attribute umbra reads whose count is not its POSITION's: glTF requires
/// one element per vertex in each, and a short one was dropped without a word (a TEXCOORD_0
/// of 1 element took the primitive's textures with it).
pub(super) fn check_attribute_counts(primitive: &gltf::Primitive) -> Result<(), String> {
    use gltf::mesh::Semantic;
    let Some(positions) = primitive.get(&Semantic::Positions) else { return Ok(()) };
    let vertices = positions.count();
    for (semantic, accessor) in primitive.attributes() {
        let read = matches!(
            semantic,
            Semantic::Normals
                | Semantic::Tangents
                | Semantic::TexCoords(_)
                | Semantic::Joints(_)
                | Semantic::Weights(_)
        );
        if read && accessor.count() != vertices {
            return Err(format!(
                "{} accessor {} has {} elements, not one per vertex ({vertices} POSITION elements)",
                semantic.to_string(),
                accessor.index(),
                accessor.count()
            ));
        }
    }
    Ok(())
}
