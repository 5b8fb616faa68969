//! Any text as a run manifest: an error or a manifest whose paths stay in its folder.
#![no_main]

use libfuzzer_sys::fuzz_target;
use unz_formats::manifest::RunManifest;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let dir = std::path::Path::new("/campaign/run");
        if let Ok(m) = RunManifest::parse(text, &dir.join("run.toml")) {
            assert!(m.raw.starts_with(dir));
            assert!(m.odometer.file.as_ref().is_none_or(|f| f.starts_with(dir)));
        }
    }
});
