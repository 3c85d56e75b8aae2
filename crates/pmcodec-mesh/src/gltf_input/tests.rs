use super::*;

#[test]
fn base64_round_trips_known_strings() {
    assert_eq!(decode_base64("TWFu").as_deref(), Some(&b"Man"[..]));
    assert_eq!(decode_base64("TWE=").as_deref(), Some(&b"Ma"[..]));
    assert_eq!(decode_base64("TQ==").as_deref(), Some(&b"M"[..]));
    assert_eq!(decode_base64("AAECAwQFBgc=").as_deref(), Some(&[0u8, 1, 2, 3, 4, 5, 6, 7][..]));
    assert_eq!(decode_base64("TW*u"), None);
}

#[test]
fn percent_decoding_rejects_broken_escapes() {
    assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
    assert_eq!(percent_decode("%ff%fe"), None);
    assert_eq!(percent_decode("%4"), None);
    assert_eq!(percent_decode("%zz"), None);
}

#[test]
fn slerp_takes_the_short_way_and_normalises() {
    let a = Quat::IDENTITY;
    let b = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
    let half = slerp(a, -b, 0.5);
    let want = Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
    assert!(half.dot(want).abs() > 1.0 - 1e-6, "{half:?}");
    assert!((slerp(a * 2.0, b * 3.0, 0.25).length() - 1.0).abs() < 1e-6);
    assert_eq!(unit_quat(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)), Quat::IDENTITY);
}

#[test]
fn glb_splitting_rejects_bad_lengths() {
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(4u32.to_le_bytes()); // shorter than the header itself
    assert!(split_glb(&glb).is_err());
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(28u32.to_le_bytes());
    glb.extend(100u32.to_le_bytes()); // chunk longer than the file
    glb.extend(b"JSON");
    glb.extend(b"{}  ");
    assert!(split_glb(&glb).is_err());
}
