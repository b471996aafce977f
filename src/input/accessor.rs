//! The glTF accessor decoder of the one glTF reader (`document.rs`), through which the loader
//! (`gltf.rs`) and the viewer (`view/glb.rs`) read every accessor, so that both read a file the
//! same way and check it the same way.
//!
//! [`decode`] takes the bytes of a buffer view and an accessor's [`Layout`], checks the layout
//! against the spec before reading a byte — at least one element, a known component type, a
//! `byteStride` no smaller than the element, every element inside the view, all computed without
//! overflow — and returns every component as `f64`: `normalized` integers mapped by the glTF 2.0
//! rules (`i8`: `max(c/127, −1)`, `u8`: `c/255`, `i16`: `max(c/32767, −1)`, `u16`: `c/65535`),
//! other integers and floats converted exactly. The reader names the file and the accessor in
//! its errors.

/// How an accessor lays out its elements in its buffer view.
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    /// glTF `componentType` (5120 i8, 5121 u8, 5122 i16, 5123 u16, 5125 u32, 5126 f32).
    pub component_type: u64,
    pub normalized: bool,
    /// Components per element (1 for SCALAR … 16 for MAT4).
    pub components: usize,
    pub count: usize,
    /// `byteOffset` of the accessor inside its view.
    pub offset: usize,
    /// The view's `byteStride`; `None` means tightly packed.
    pub stride: Option<usize>,
}

/// Why a layout cannot be read; the caller adds the file and the accessor.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LayoutError {
    #[error("has no elements (count must be at least 1)")]
    Empty,
    #[error("component type {0} is unknown")]
    ComponentType(u64),
    #[error("byteStride {stride} is smaller than the accessor's {element}-byte element")]
    StrideTooSmall { stride: usize, element: usize },
    #[error("reads {need} bytes, past the end of its {have}-byte buffer view")]
    PastTheView { need: usize, have: usize },
    #[error("byte range overflows")]
    Overflow,
}

/// Bytes per component of a glTF component type.
pub fn component_size(component_type: u64) -> Option<usize> {
    match component_type {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

/// The value a normalized integer component `v` of `component_type` stands for (the spec's
/// rules, see the module doc); other types are returned as they are. Accessor bounds of a
/// normalized accessor are integers too and read the same way.
pub fn normalized_value(component_type: u64, v: f64) -> f64 {
    match component_type {
        5120 => (v / 127.0).max(-1.0),
        5121 => v / 255.0,
        5122 => (v / 32767.0).max(-1.0),
        5123 => v / 65535.0,
        _ => v,
    }
}

/// Checks `layout` against `view` (see the module doc) and decodes every component.
pub fn decode(view: &[u8], layout: &Layout) -> Result<Vec<f64>, LayoutError> {
    if layout.count == 0 {
        return Err(LayoutError::Empty);
    }
    let ct = layout.component_type;
    let comp = component_size(ct).ok_or(LayoutError::ComponentType(ct))?;
    let element = comp
        .checked_mul(layout.components)
        .ok_or(LayoutError::Overflow)?;
    let stride = layout.stride.unwrap_or(element);
    if stride < element {
        return Err(LayoutError::StrideTooSmall { stride, element });
    }
    let need = stride
        .checked_mul(layout.count - 1)
        .and_then(|s| s.checked_add(layout.offset))
        .and_then(|s| s.checked_add(element))
        .ok_or(LayoutError::Overflow)?;
    if need > view.len() {
        return Err(LayoutError::PastTheView {
            need,
            have: view.len(),
        });
    }
    let norm = layout.normalized;
    let mut out = Vec::with_capacity(layout.count * layout.components);
    for e in 0..layout.count {
        let start = layout.offset + e * stride;
        for c in view[start..start + element].chunks_exact(comp) {
            let v = match ct {
                5120 => c[0] as i8 as f64,
                5121 => c[0] as f64,
                5122 => i16::from_le_bytes([c[0], c[1]]) as f64,
                5123 => u16::from_le_bytes([c[0], c[1]]) as f64,
                5125 => u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64,
                _ => f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64,
            };
            out.push(if norm { normalized_value(ct, v) } else { v });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(component_type: u64, components: usize, count: usize) -> Layout {
        Layout {
            component_type,
            normalized: false,
            components,
            count,
            offset: 0,
            stride: None,
        }
    }

    #[test]
    fn a_stride_under_the_element_is_refused() {
        let l = Layout {
            stride: Some(4),
            ..layout(5126, 3, 3)
        };
        assert_eq!(
            decode(&[0; 36], &l),
            Err(LayoutError::StrideTooSmall {
                stride: 4,
                element: 12
            })
        );
    }

    #[test]
    fn counts_that_overflow_or_pass_the_view_are_refused() {
        let l = Layout {
            stride: Some(usize::MAX / 2),
            ..layout(5126, 1, 4)
        };
        assert_eq!(decode(&[0; 4], &l), Err(LayoutError::Overflow));
        assert!(matches!(
            decode(&[0; 8], &layout(5126, 3, 1)),
            Err(LayoutError::PastTheView { need: 12, have: 8 })
        ));
        assert_eq!(
            decode(&[0; 8], &layout(5126, 3, 0)),
            Err(LayoutError::Empty)
        );
        assert_eq!(
            decode(&[0; 8], &layout(7, 1, 1)),
            Err(LayoutError::ComponentType(7))
        );
    }

    #[test]
    fn normalized_integers_follow_the_spec() {
        let l = Layout {
            normalized: true,
            ..layout(5120, 2, 1)
        };
        assert_eq!(decode(&[0x80, 127], &l).unwrap(), vec![-1.0, 1.0]);
        let l = Layout {
            normalized: true,
            ..layout(5123, 1, 1)
        };
        assert_eq!(decode(&[0xff, 0xff], &l).unwrap(), vec![1.0]);
        assert_eq!(decode(&[7, 1], &layout(5123, 1, 1)).unwrap(), vec![263.0]);
    }
}
