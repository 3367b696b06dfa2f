//! Build script of the cooking library. `intel_tex_2` ships prebuilt ISPC kernels that need the
//! C++ runtime (`__gxx_personality_v0`), which rustc's default link line does not bring in;
//! linking libstdc++ here fixes every binary, test and bench that links this crate.

fn main() {
    println!("cargo:rustc-link-lib=dylib=stdc++");
    println!("cargo:rerun-if-changed=build.rs");
}
