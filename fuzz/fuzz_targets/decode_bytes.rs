//! Fuzz target: see `pifs_tests::fuzz::decode_bytes`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| pifs_tests::fuzz::decode_bytes(data));
