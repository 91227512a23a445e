//! glTF accessors: bounds-checked, strided reads of buffer views into vertex attributes and
//! indices.

use super::*;

impl Loader<'_> {
    /// The bytes of buffer view `index`, bounds-checked.
    pub(super) fn view_bytes(&self, index: usize) -> Result<&[u8], LoadError> {
        let view = self.doc.views().nth(index);
        let slice = view.as_ref().and_then(|v| {
            let data = self.buffers.get(v.buffer().index())?;
            data.get(v.offset()..v.offset().checked_add(v.length())?)
        });
        slice.ok_or_else(|| {
            self.error(LoadErrorKind::Malformed, format!("buffer view {index} lies outside its buffer"))
                .at(format!("buffer view {index}"))
        })
    }

    pub(super) fn read_vec3(&self, accessor: &gltf::Accessor) -> Result<Vec<Vec3>, LoadError> {
        let flat = self.read_floats(accessor, Dimensions::Vec3)?;
        Ok(flat.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
    }

    /// Reads a float accessor (or normalised integers) of the given shape as a flat list.
    pub(super) fn read_floats(&self, accessor: &gltf::Accessor, dims: Dimensions) -> Result<Vec<f32>, LoadError> {
        let ty = accessor.data_type();
        let float_ok = ty == DataType::F32 || (accessor.normalized() && dims == Dimensions::Vec2);
        if accessor.dimensions() != dims || !float_ok {
            let message = format!(
                "has type {:?} of {:?}{}; expected {dims:?} of F32",
                accessor.dimensions(),
                ty,
                if accessor.normalized() { " (normalized)" } else { "" }
            );
            return Err(self.error(LoadErrorKind::Unsupported, message).at(format!("accessor {}", accessor.index())));
        }
        let normalized = accessor.normalized();
        self.read_accessor(accessor, |b| decode_float(b, ty, normalized))
    }

    pub(super) fn read_indices(&self, accessor: &gltf::Accessor) -> Result<Vec<u32>, LoadError> {
        let ty = accessor.data_type();
        if accessor.dimensions() != Dimensions::Scalar || !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32) {
            let message =
                format!("indices have type {:?} of {ty:?}; expected an unsigned scalar", accessor.dimensions());
            return Err(self.error(LoadErrorKind::Malformed, message).at(format!("accessor {}", accessor.index())));
        }
        self.read_accessor(accessor, |b| decode_uint(b, ty))
    }

    /// Reads every component of `accessor` (dense part, then sparse substitutions) with
    /// `decode`, which is given exactly one component's bytes. All ranges are checked first.
    pub(super) fn read_accessor<T: Copy + Default>(
        &self,
        accessor: &gltf::Accessor,
        decode: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, LoadError> {
        let place = format!("accessor {}", accessor.index());
        let malformed = |m: String| self.error(LoadErrorKind::Malformed, m).at(place.clone());
        let count = accessor.count();
        let comps = accessor.dimensions().multiplicity();
        let comp_size = accessor.data_type().size();
        let elem_size = comps * comp_size;
        let mut out = match accessor.view() {
            Some(view) => {
                let bytes = self.view_bytes(view.index()).map_err(|e| within(e, &place))?;
                let stride = view.stride().unwrap_or(elem_size);
                let strided = Strided { bytes, offset: accessor.offset(), stride, count, elem_size };
                strided.check().map_err(malformed)?;
                strided.read(comps, comp_size, &decode)
            }
            None => {
                if count > MAX_ZERO_ACCESSOR_COUNT {
                    return Err(malformed(format!("declares {count} elements without any data")));
                }
                vec![T::default(); count * comps]
            }
        };
        if let Some(sparse) = accessor.sparse() {
            let k = sparse.count();
            let idx = sparse.indices();
            let idx_ty = match idx.index_type() {
                gltf::accessor::sparse::IndexType::U8 => DataType::U8,
                gltf::accessor::sparse::IndexType::U16 => DataType::U16,
                gltf::accessor::sparse::IndexType::U32 => DataType::U32,
            };
            let idx_bytes = self.view_bytes(idx.view().index()).map_err(|e| within(e, &place))?;
            let idx_size = idx_ty.size();
            let targets =
                Strided { bytes: idx_bytes, offset: idx.offset(), stride: idx_size, count: k, elem_size: idx_size };
            targets.check().map_err(|what| malformed(format!("sparse indices: {what}")))?;
            let targets = targets.read(1, idx_size, &|b| decode_uint(b, idx_ty));
            let val_bytes = self.view_bytes(sparse.values().view().index()).map_err(|e| within(e, &place))?;
            let values =
                Strided { bytes: val_bytes, offset: sparse.values().offset(), stride: elem_size, count: k, elem_size };
            values.check().map_err(|what| malformed(format!("sparse values: {what}")))?;
            let values = values.read(comps, comp_size, &decode);
            for (j, &target) in targets.iter().enumerate() {
                let t = target as usize;
                let (Some(dst), Some(src)) =
                    (out.get_mut(t * comps..(t + 1) * comps), values.get(j * comps..(j + 1) * comps))
                else {
                    return Err(malformed(format!("sparse index {target} is outside the {count} elements")));
                };
                dst.copy_from_slice(src);
            }
        }
        Ok(out)
    }
}

/// `count` elements of `elem_size` bytes, `stride` apart from `offset` in `bytes`.
struct Strided<'b> {
    bytes: &'b [u8],
    offset: usize,
    stride: usize,
    count: usize,
    elem_size: usize,
}

impl Strided<'_> {
    /// Checks that every element lies inside `bytes`; the error says why not.
    pub(super) fn check(&self) -> Result<(), String> {
        if self.stride < self.elem_size {
            return Err(format!("byte stride {} is smaller than the element size {}", self.stride, self.elem_size));
        }
        if self.count == 0 {
            return Ok(());
        }
        let end = (self.count - 1)
            .checked_mul(self.stride)
            .and_then(|s| s.checked_add(self.offset))
            .and_then(|s| s.checked_add(self.elem_size));
        match end {
            Some(end) if end <= self.bytes.len() => Ok(()),
            _ => Err(format!(
                "buffer too short for this accessor: {} elements of {} bytes from byte {} overrun the view's {} bytes",
                self.count,
                self.elem_size,
                self.offset,
                self.bytes.len()
            )),
        }
    }

    /// Decodes all components; only call after [`Strided::check`] succeeded.
    pub(super) fn read<T>(&self, comps: usize, comp_size: usize, decode: &impl Fn(&[u8]) -> T) -> Vec<T> {
        let mut out = Vec::with_capacity(self.count * comps);
        for i in 0..self.count {
            let start = self.offset + i * self.stride;
            for c in 0..comps {
                let at = start + c * comp_size;
                if let Some(b) = self.bytes.get(at..at + comp_size) {
                    out.push(decode(b));
                }
            }
        }
        out
    }
}

/// One little-endian component as `f32` (normalised integers mapped to [0, 1] or [−1, 1]).
fn decode_float(b: &[u8], ty: DataType, normalized: bool) -> f32 {
    let (value, max) = match (ty, b) {
        (DataType::F32, [x, y, z, w, ..]) => return f32::from_le_bytes([*x, *y, *z, *w]),
        (DataType::U8, [x, ..]) => (*x as f32, 255.0),
        (DataType::I8, [x, ..]) => (*x as i8 as f32, 127.0),
        (DataType::U16, [x, y, ..]) => (u16::from_le_bytes([*x, *y]) as f32, 65535.0),
        (DataType::I16, [x, y, ..]) => (i16::from_le_bytes([*x, *y]) as f32, 32767.0),
        (DataType::U32, [x, y, z, w, ..]) => (u32::from_le_bytes([*x, *y, *z, *w]) as f32, u32::MAX as f32),
        _ => return 0.0,
    };
    if normalized { (value / max).max(-1.0) } else { value }
}

/// One little-endian unsigned component as `u32`.
fn decode_uint(b: &[u8], ty: DataType) -> u32 {
    match (ty, b) {
        (DataType::U8, [x, ..]) => *x as u32,
        (DataType::U16, [x, y, ..]) => u16::from_le_bytes([*x, *y]) as u32,
        (DataType::U32, [x, y, z, w, ..]) => u32::from_le_bytes([*x, *y, *z, *w]),
        _ => 0,
    }
}
