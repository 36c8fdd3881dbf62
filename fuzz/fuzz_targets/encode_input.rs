//! Fuzz target: see `pifs_tests::fuzz::encode_input`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| pifs_tests::fuzz::encode_input(data));
