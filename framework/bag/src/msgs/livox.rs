//! `livox_ros_driver/CustomMsg` (and `livox_ros_driver2/CustomMsg`): Livox's own point-cloud message,
//! `timebase` (ns) plus an array of `CustomPoint {offset_time (ns from timebase), x, y, z, reflectivity,
//! tag, line}`. It is decoded from the definition the bag stores with the connection, so field order and
//! types come from the recording, not from an assumption about the driver version.

use skid_msgs::RawPoint;

use crate::error::DecodeError;
use crate::msgs::definition::{self, Definitions, Scalar, Visitor};
use crate::wire::{Header, WireReader};

/// Whether `message_type` is a Livox custom point-cloud message.
pub fn is_livox_custom(message_type: &str) -> bool {
    matches!(
        message_type,
        "livox_ros_driver/CustomMsg" | "livox_ros_driver2/CustomMsg"
    )
}

/// A decoded Livox cloud: its header and the points with time offsets from the header stamp.
#[derive(Clone, Debug, Default)]
pub struct LivoxCloud {
    pub header: Header,
    pub points: Vec<RawPoint>,
    pub dropped_non_finite: usize,
}

#[derive(Default)]
struct CloudVisitor {
    cloud: LivoxCloud,
    timebase_nanos: f64,
    point: [f64; 6],
}

const X: usize = 0;
const Y: usize = 1;
const Z: usize = 2;
const REFLECTIVITY: usize = 3;
const OFFSET_TIME: usize = 4;
const LINE: usize = 5;

struct PointVisitor<'a>(&'a mut [f64; 6]);

impl Visitor for PointVisitor<'_> {
    fn scalar(&mut self, field: &str, value: Scalar) {
        let Scalar::Number(value) = value else { return };
        let slot = match field {
            "x" => X,
            "y" => Y,
            "z" => Z,
            "reflectivity" => REFLECTIVITY,
            "offset_time" => OFFSET_TIME,
            "line" => LINE,
            _ => return,
        };
        self.0[slot] = value;
    }
}

impl Visitor for CloudVisitor {
    fn header(&mut self, header: Header) {
        self.cloud.header = header;
    }

    fn scalar(&mut self, field: &str, value: Scalar) {
        if let ("timebase", Scalar::Number(nanos)) = (field, value) {
            self.timebase_nanos = nanos;
        }
    }

    fn sequence(&mut self, field: &str, count: usize) -> bool {
        if field == "points" {
            self.cloud.points.reserve(count);
        }
        field == "points"
    }

    fn element(
        &mut self,
        reader: &mut WireReader<'_>,
        definitions: &Definitions,
        type_name: &str,
    ) -> Result<(), DecodeError> {
        self.point = [
            f64::NAN,
            f64::NAN,
            f64::NAN,
            0.0,
            0.0,
            f64::from(RawPoint::UNKNOWN_RING),
        ];
        definition::walk(reader, definitions, type_name, &mut PointVisitor(&mut self.point))?;
        let [x, y, z, reflectivity, offset_time, line] = self.point;
        let (x, y, z) = (x as f32, y as f32, z as f32);
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            self.cloud.dropped_non_finite += 1;
            return Ok(());
        }
        let stamp_nanos = self.cloud.header.stamp_nanos as f64;
        let time_offset_s = ((self.timebase_nanos + offset_time - stamp_nanos) * 1e-9) as f32;
        self.cloud.points.push(RawPoint::new(
            x,
            y,
            z,
            reflectivity as f32,
            time_offset_s,
            line as u16,
        ));
        Ok(())
    }
}

/// Decodes one CustomMsg with the definition text its connection carries.
pub fn decode_livox_custom(
    reader: &mut WireReader<'_>,
    message_type: &str,
    definition_text: &str,
) -> Result<LivoxCloud, DecodeError> {
    if definition_text.trim().is_empty() {
        return Err(DecodeError::new(format!(
            "{message_type}: the bag stores no message definition for it"
        )));
    }
    let definitions = definition::parse(message_type, definition_text)?;
    let mut visitor = CloudVisitor::default();
    definition::walk(reader, &definitions, message_type, &mut visitor)?;
    Ok(visitor.cloud)
}
