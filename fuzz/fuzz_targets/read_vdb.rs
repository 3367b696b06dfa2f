//! Fuzz target: any bytes through the whole reader (open, read every float grid, stats).
//! Seed the corpus with `fixtures/vdb/*.vdb`. Must never panic or abort.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(f) = vdbcook_vdb::VdbFile::from_bytes(std::path::Path::new("fuzz.vdb"), data.to_vec()) {
        for i in 0..f.grids.len() {
            if let Ok(g) = f.read_float_grid(i) {
                let _ = g.stats();
            }
        }
    }
});
