//! Generates Rust bindings for whichever Embree is installed (4 preferred,
//! then 3) and tells the crate which one through `cfg(embree_version = "N")`.
//!
//! Lookup order: `$EMBREE_DIR` (a prefix holding `include/embree{4,3}` and
//! `lib`), then Debian's `/usr/include/embree4`, then `/usr/include/embree3`.

use std::env;
use std::path::{Path, PathBuf};

struct Embree {
    version: u32,
    header: PathBuf,
    include_dir: PathBuf,
    lib_dir: Option<PathBuf>,
}

fn find_in_prefix(prefix: &Path) -> Option<Embree> {
    [4, 3].into_iter().find_map(|version| {
        let header = prefix.join(format!("include/embree{version}/rtcore.h"));
        header.is_file().then(|| Embree {
            version,
            header,
            include_dir: prefix.join("include"),
            lib_dir: Some(prefix.join("lib")),
        })
    })
}

fn find_embree() -> Option<Embree> {
    if let Some(dir) = env::var_os("EMBREE_DIR") {
        return find_in_prefix(Path::new(&dir));
    }
    [4, 3].into_iter().find_map(|version| {
        let header = PathBuf::from(format!("/usr/include/embree{version}/rtcore.h"));
        header.is_file().then(|| Embree {
            version,
            header,
            include_dir: PathBuf::from("/usr/include"),
            lib_dir: None,
        })
    })
}

fn main() {
    println!("cargo::rerun-if-env-changed=EMBREE_DIR");
    println!("cargo::rustc-check-cfg=cfg(embree_version, values(\"3\", \"4\"))");

    let Some(embree) = find_embree() else {
        panic!(
            "Embree not found (looked in $EMBREE_DIR, /usr/include/embree4, /usr/include/embree3): \
             install it with `sudo apt-get install libembree-dev libclang-dev` (or run `make`, which does)"
        );
    };
    println!("cargo::rerun-if-changed={}", embree.header.display());
    println!("cargo::rustc-cfg=embree_version=\"{}\"", embree.version);
    if let Some(lib_dir) = &embree.lib_dir {
        println!("cargo::rustc-link-search=native={}", lib_dir.display());
    }
    println!("cargo::rustc-link-lib=embree{}", embree.version);

    let bindings = bindgen::Builder::default()
        .header(embree.header.to_string_lossy())
        .clang_arg(format!("-I{}", embree.include_dir.display()))
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC.*")
        // Values that come back from C (errors, flags) may hold anything the
        // library returns; a Rust enum would make an unknown value UB.
        .default_enum_style(bindgen::EnumVariation::NewType {
            is_bitfield: false,
            is_global: false,
        })
        .bitfield_enum("RTC.*Flags")
        .size_t_is_usize(true)
        .layout_tests(true)
        .derive_default(true)
        .generate()
        .unwrap_or_else(|err| panic!("bindgen failed on {}: {err}", embree.header.display()));

    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    bindings
        .write_to_file(out.join("embree_bindings.rs"))
        .expect("write Embree bindings");
}
