//! The OBJ parser (uploads reach it from the network) on hostile text: arbitrary bytes, and
//! lines built from OBJ's own words with wrong counts, bad numbers and out-of-range indices,
//! give a frame or an error, never a panic; a frame that parses only indexes its own vertices.

use pmcodec_mesh::obj::parse_obj;
use proptest::prelude::*;
use std::path::Path;

fn word() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("v".to_string()),
        Just("f".to_string()),
        Just("vn".to_string()),
        Just("#".to_string()),
        (-5i64..12).prop_map(|i| i.to_string()),
        (-5i64..12).prop_map(|i| format!("{i}/{i}/{i}")),
        (-5i64..12).prop_map(|i| format!("{i}//")),
        any::<f32>().prop_map(|x| x.to_string()),
        Just("nan".to_string()),
        Just("4294967296".to_string()),
        Just("-9223372036854775808".to_string()),
        "[ -~]{0,6}",
    ]
}

proptest! {
    #[test]
    fn arbitrary_text_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(frame) = parse_obj(&text, Path::new("fuzz.obj")) {
            prop_assert!(frame.triangles.iter().flatten().all(|&i| (i as usize) < frame.positions.len()));
        }
    }

    #[test]
    fn obj_like_lines_never_panic(lines in prop::collection::vec(prop::collection::vec(word(), 0..7), 0..30)) {
        let text: String = lines.iter().map(|l| l.join(" ") + "\n").collect();
        match parse_obj(&text, Path::new("fuzz.obj")) {
            Ok(frame) => prop_assert!(frame.triangles.iter().flatten().all(|&i| (i as usize) < frame.positions.len())),
            // Errors name the file.
            Err(e) => prop_assert!(e.to_string().contains("fuzz.obj"), "{}", e),
        }
    }
}
