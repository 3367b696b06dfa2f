//! Fuzz target: any bytes through the blosc decoder with a bounded output. Must never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = vdbcook_blosc::decompress(data, 1 << 20);
});
