//! glTF input: see the module below.
