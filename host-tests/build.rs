//! Builds the C reference host (`c-host/`, issue 16 item 5) and its test drive with the system
//! C compiler, warnings as errors, for the end-to-end test `tests/c_host.rs`.
fn main() {
    // The manifest directory at run time (`env!` would bake in the tree the build script was
    // compiled in: a copied target directory then compiled and watched another checkout).
    let dir = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let root = std::path::Path::new(&dir).join("../c-host");
    for f in ["include/pbcard_dpm.h", "include/pbcard_host.h", "src/pbcard_host.c", "test/drive.c"] {
        println!("cargo:rerun-if-changed={}", root.join(f).display());
    }
    cc::Build::new()
        .include(root.join("include"))
        .file(root.join("src/pbcard_host.c"))
        .file(root.join("test/drive.c"))
        .flag("-std=c99")
        .flag("-pedantic")
        .flag("-Wall")
        .flag("-Wextra")
        .flag("-Werror")
        .warnings_into_errors(true)
        .compile("pbcard_c_host");
}
