// The one error type of the TypeScript decoder, as `pmcodec_container::ContainerError` is the
// Rust decoder's: every message names the region or chunk at fault ("frame 12 band 3
// positions: checksum mismatch").

/** Bad input: a file, chunk or delta that does not decode. */
export class DecodeError extends Error {}
