//! The firmware's link: puts the workspace root, where `memory.x` (the STM32F411's memory map,
//! which cortex-m-rt's `link.x` includes) lives, on the linker's search path, so the ELF links
//! whichever directory cargo runs the linker from.

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let root = std::path::Path::new(&manifest).parent().expect("firmware/ is in the workspace root");
    println!("cargo:rustc-link-search={}", root.display());
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
