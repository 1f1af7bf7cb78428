//! The MCAP records SKiD reads (Schema 0x03, Channel 0x04, Message 0x05; mcap.dev/spec), parsed only
//! after their length-prefixed fields are checked against the record's own length: the `mcap` crate
//! reserves a string's or byte array's announced length before reading it, so a lying prefix in a small
//! record would otherwise allocate gigabytes (found by fuzzing). Other records are skipped unparsed.

use mcap::records::Record;

const SCHEMA: u8 = 0x03;
const CHANNEL: u8 = 0x04;
const MESSAGE: u8 = 0x05;

/// A cursor over a record body that checks every field fits.
struct Fields<'a> {
    rest: &'a [u8],
}

impl Fields<'_> {
    fn skip(&mut self, bytes: usize, what: &str) -> Result<(), String> {
        if bytes > self.rest.len() {
            return Err(format!(
                "{what} announces {bytes} bytes, but only {} remain in the record",
                self.rest.len()
            ));
        }
        self.rest = &self.rest[bytes..];
        Ok(())
    }

    /// A `uint32` length and that many bytes (a string or byte array); returns those bytes.
    fn prefixed(&mut self, what: &str) -> Result<&[u8], String> {
        let length = self
            .rest
            .get(..4)
            .and_then(|bytes| bytes.try_into().ok())
            .map(u32::from_le_bytes)
            .ok_or_else(|| format!("{what}'s length is cut off"))?;
        let body = &self.rest[4..];
        self.rest = body;
        self.skip(length as usize, what)?;
        Ok(&body[..length as usize])
    }

    /// A string map: a `uint32` byte length, then key and value strings that must fill it exactly.
    fn string_map(&mut self, what: &str) -> Result<(), String> {
        let mut entries = Fields {
            rest: self.prefixed(what)?,
        };
        while !entries.rest.is_empty() {
            entries.prefixed(what)?;
            entries.prefixed(what)?;
        }
        Ok(())
    }
}

/// Checks the length prefixes of the record kinds SKiD parses.
fn check_lengths(opcode: u8, body: &[u8]) -> Result<(), String> {
    let mut fields = Fields { rest: body };
    match opcode {
        SCHEMA => {
            fields.skip(2, "schema id")?;
            fields.prefixed("schema name")?;
            fields.prefixed("schema encoding")?;
            fields.prefixed("schema data").map(drop)
        }
        CHANNEL => {
            fields.skip(4, "channel and schema ids")?;
            fields.prefixed("topic")?;
            fields.prefixed("message encoding")?;
            fields.string_map("channel metadata")
        }
        MESSAGE => fields.skip(2 + 4 + 8 + 8, "message header"),
        _ => Ok(()),
    }
}

/// The record, when it is one SKiD reads (`None` for the others); an error names what does not fit.
pub fn parse_known(opcode: u8, body: &[u8]) -> Result<Option<Record<'_>>, String> {
    if !matches!(opcode, SCHEMA | CHANNEL | MESSAGE) {
        return Ok(None);
    }
    check_lengths(opcode, body)?;
    mcap::parse_record(opcode, body)
        .map(Some)
        .map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_string_longer_than_its_record_is_refused_before_parsing() {
        // A channel whose topic claims 1.9 GB in a 20-byte record.
        let mut body = vec![1, 0, 1, 0];
        body.extend_from_slice(&0x7300_0000u32.to_le_bytes());
        body.extend_from_slice(b"/points");
        let error = parse_known(CHANNEL, &body).err().unwrap_or_default();
        assert!(error.contains("topic announces"), "{error}");
        assert!(
            matches!(parse_known(0x01, &body), Ok(None)),
            "headers are skipped"
        );
        // A metadata map whose one key claims 4 GB inside an 8-byte map.
        let mut body = vec![1, 0, 1, 0];
        for text in [&b"/points"[..], b"cdr"] {
            body.extend_from_slice(&(text.len() as u32).to_le_bytes());
            body.extend_from_slice(text);
        }
        body.extend_from_slice(&8u32.to_le_bytes());
        body.extend_from_slice(&u32::MAX.to_le_bytes());
        body.extend_from_slice(b"abcd");
        let error = parse_known(CHANNEL, &body).err().unwrap_or_default();
        assert!(error.contains("channel metadata announces"), "{error}");
    }
}
