//! The session harnesses (`skid-session`): a robot's `descriptors.bin` alone, and a whole session folder
//! (manifest, one robot's keyframes, descriptors and pose graph) read back as `skid run --set
//! prior.path=…` and `skid session merge` read one.

use skid_session::{decode_descriptors, encode_descriptors, read_session};

use crate::scratch::with_folder;

/// An accepted descriptor file holds entries of the announced length, and encodes back to its bytes.
pub fn session_descriptors(data: &[u8]) {
    let Ok((length, entries)) = decode_descriptors(data) else {
        return;
    };
    assert!(entries.iter().all(|(_, values)| values.len() == length));
    let borrowed: Vec<(u32, &[f32])> = entries.iter().map(|(i, v)| (*i, v.as_slice())).collect();
    let again = encode_descriptors(length, &borrowed).expect("an accepted file encodes again");
    assert_eq!(again, data, "a descriptor file does not encode back to its bytes");
}

/// The bytes between separators, in order: a session folder's files.
pub const SESSION_FILE_SEPARATOR: &[u8] = b"\n--skid-session-file--\n";

/// The files a session-folder input stands for, in the order its parts come.
pub const SESSION_FILES: [&str; 4] = [
    "session.json",
    "robot0/keyframes.json",
    "robot0/descriptors.bin",
    "robot0/pose_graph.g2o",
];

fn split(data: &[u8]) -> Vec<&[u8]> {
    let mut parts = Vec::new();
    let mut rest = data;
    while let Some(at) = rest
        .windows(SESSION_FILE_SEPARATOR.len())
        .position(|window| window == SESSION_FILE_SEPARATOR)
    {
        parts.push(&rest[..at]);
        rest = &rest[at + SESSION_FILE_SEPARATOR.len()..];
    }
    parts.push(rest);
    parts
}

/// A session that reads names only keyframes its files hold, each with a descriptor of the announced
/// length, and robots in ascending order.
pub fn session_folder(data: &[u8]) {
    let parts = split(data);
    let files: Vec<(&str, &[u8])> = SESSION_FILES.iter().copied().zip(parts).collect();
    let Some(Ok(session)) = with_folder(&files, read_session) else {
        return;
    };
    let length = session.descriptor.as_ref().map(|spec| spec.length);
    for pair in session.robots.windows(2) {
        assert!(pair[0].robot < pair[1].robot, "robots out of order");
    }
    for robot in &session.robots {
        for pair in robot.keyframes.windows(2) {
            assert!(pair[0].index < pair[1].index, "keyframes out of order");
        }
        for keyframe in &robot.keyframes {
            if let Some(values) = &keyframe.descriptor {
                assert_eq!(Some(values.len()), length, "a descriptor of another length");
            }
            assert!(skid_core::pose::is_finite(&keyframe.map_from_sensor));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seed_session_is_read_back_whole() {
        let seeds = crate::seeds::seeds("session_folder");
        let parts = split(&seeds[0]);
        assert_eq!(parts.len(), SESSION_FILES.len());
        let files: Vec<(&str, &[u8])> = SESSION_FILES.iter().copied().zip(parts).collect();
        let session = with_folder(&files, read_session).unwrap().unwrap();
        assert_eq!(session.robots[0].keyframes.len(), 3);
        assert_eq!(session.robots[0].graph.vertices.len(), 3);
    }
}
