//! Acceptance 6: core's source has no std, alloc or panicking shortcut outside its tests.

use std::path::Path;

#[test]
fn core_source_has_no_std_alloc_or_panic_paths() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../core/src");
    let forbidden = [
        "std::",
        "extern crate std",
        "extern crate alloc",
        "alloc::",
        ".unwrap()",
        ".expect(",
        "panic!(",
        "unreachable!(",
        "todo!(",
        "unimplemented!(",
    ];
    let mut files = 0;
    let mut stack = vec![src];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("core/src") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().and_then(|e| e.to_str()) != Some("rs") {
                continue;
            }
            files += 1;
            let text = std::fs::read_to_string(&path).expect("source");
            // Everything from the test module on is test code.
            let code = text.split("#[cfg(test)]").next().unwrap_or("");
            for (i, line) in code.lines().enumerate() {
                let line = line.trim_start();
                if line.starts_with("//") {
                    continue;
                }
                for f in forbidden {
                    assert!(
                        !line.contains(f),
                        "{}:{}: `{f}` in core: {line}",
                        path.display(),
                        i + 1
                    );
                }
            }
            assert!(!code.contains("#![no_std]") || path.ends_with("lib.rs"));
        }
    }
    assert!(files >= 10, "only {files} core files found");
    let lib =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../core/src/lib.rs"))
            .expect("lib.rs");
    assert!(lib.contains("#![no_std]"));
}
