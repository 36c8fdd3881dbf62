//! Fuzz target: see `pifs_tests::fuzz::large_dimensions`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| pifs_tests::fuzz::large_dimensions(data));
