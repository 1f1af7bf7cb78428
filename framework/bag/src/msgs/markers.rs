//! `visualization_msgs/MarkerArray` as ROS 2 Jazzy defines it (CDR), read for its markers' namespaces,
//! types and points: what `skid plot` needs from a run record's loop lines. Every field is walked, so a
//! marker with a texture, UV coordinates or a mesh is read past correctly.

use crate::error::DecodeError;
use crate::wire::WireReader;

/// One marker's namespace, type and points (in its header's frame).
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerPoints {
    pub namespace: String,
    pub marker_type: i32,
    pub points: Vec<[f64; 3]>,
}

/// Decodes every marker of a `MarkerArray`.
pub fn decode_marker_array(reader: &mut WireReader<'_>) -> Result<Vec<MarkerPoints>, DecodeError> {
    // A marker takes well over 100 bytes (header, pose, scale, colour, lifetime, sequences, strings).
    let count = reader.sequence_len(100)?;
    let mut markers = Vec::with_capacity(count);
    for _ in 0..count {
        reader.header()?;
        let namespace = reader.string()?;
        let _id = reader.i32()?;
        let marker_type = reader.i32()?;
        let _action = reader.i32()?;
        reader.f64_array::<7>()?; // pose
        reader.f64_array::<3>()?; // scale
        for _ in 0..4 {
            reader.f32()?; // colour
        }
        reader.i32()?; // lifetime seconds
        reader.u32()?; // lifetime nanoseconds
        reader.bool()?; // frame_locked
        let point_count = reader.sequence_len(24)?;
        let mut points = Vec::with_capacity(point_count);
        for _ in 0..point_count {
            points.push(reader.f64_array::<3>()?);
        }
        let colour_count = reader.sequence_len(16)?;
        for _ in 0..colour_count * 4 {
            reader.f32()?;
        }
        reader.string()?; // texture_resource
        reader.header()?; // texture: a CompressedImage
        reader.string()?;
        reader.byte_sequence()?;
        let uv_count = reader.sequence_len(8)?;
        for _ in 0..uv_count * 2 {
            reader.f32()?;
        }
        reader.string()?; // text
        reader.string()?; // mesh_resource
        reader.string()?; // mesh_file: file name and data
        reader.byte_sequence()?;
        reader.bool()?; // mesh_use_embedded_materials
        markers.push(MarkerPoints {
            namespace,
            marker_type,
            points,
        });
    }
    Ok(markers)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Encoding;
    use crate::write::viz::{LineListMarker, line_markers};

    #[test]
    fn line_lists_written_by_the_record_read_back() {
        let markers = vec![
            LineListMarker {
                namespace: "accepted".into(),
                id: 0,
                rgba: [0.0, 1.0, 0.0, 1.0],
                line_width_m: 0.3,
                segments: vec![([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])],
            },
            LineListMarker {
                namespace: "undecided".into(),
                id: 1,
                rgba: [0.5; 4],
                line_width_m: 0.3,
                segments: Vec::new(),
            },
        ];
        let bytes = line_markers(7, "map", &markers);
        let mut reader = WireReader::new(&bytes, Encoding::Cdr).unwrap();
        let read = decode_marker_array(&mut reader).unwrap();
        assert_eq!(read.len(), 2);
        assert_eq!(read[0].namespace, "accepted");
        assert_eq!(read[0].marker_type, 5);
        assert_eq!(read[0].points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert!(read[1].points.is_empty());
        assert_eq!(reader.remaining(), 0);
    }
}
