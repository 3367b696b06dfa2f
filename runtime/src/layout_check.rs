//! Checks that the Rust mirrors of the WGSL uniform structs (`VolumeInfo`, `GroupInfo`,
//! `Params`, `DrawView`, `DrawInstance`) have the layout the shaders see: naga (wgpu 30's
//! shader compiler; the struct rules are WGSL's, the same in naga 29) parses the WGSL and lays the struct out by WGSL's rules; every WGSL member
//! must sit inside the Rust field of its name (`x0`, `x1`, … inside an array field `x`), at the
//! same offset for a plain field, every Rust field must start where a member starts, and the
//! sizes must be equal. A field added, dropped, reordered or resized on one side only fails
//! (the scalar kinds are not compared: a `u32` and an `f32` at the same place pass).
//! Test-only: the structs stay hand-written next to the code that fills them.

use naga::proc::Layouter;

/// One field: name, byte offset, byte size.
pub type Field = (&'static str, usize, usize);

/// The layout of a `#[repr(C)]` struct: `rust_layout!(T { a, b, c })` lists every field (the
/// exhaustive pattern below does not compile if one is left out).
macro_rules! rust_layout {
    ($t:ident { $($f:ident),* $(,)? }) => {{
        let z: $t = bytemuck::Zeroable::zeroed();
        let $t { $($f: _),* } = z;
        let fields: Vec<$crate::layout_check::Field> = vec![$((
            stringify!($f),
            std::mem::offset_of!($t, $f),
            std::mem::size_of_val(&z.$f),
        )),*];
        (std::mem::size_of::<$t>(), fields)
    }};
}
pub(crate) use rust_layout;

/// The WGSL layout of struct `name` in `source`: its size and members (name, offset, size).
fn wgsl_layout(source: &str, name: &str) -> (usize, Vec<(String, usize, usize)>) {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("WGSL does not parse: {}", e.emit_to_string(source)));
    let mut layouter = Layouter::default();
    layouter.update(module.to_ctx()).expect("WGSL layout");
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name} in the WGSL"));
    let naga::TypeInner::Struct { members, span } = &ty.1.inner else {
        panic!("{name} is not a struct");
    };
    let members = members
        .iter()
        .map(|m| {
            (
                m.name.clone().unwrap_or_default(),
                m.offset as usize,
                layouter[m.ty].size as usize,
            )
        })
        .collect();
    (*span as usize, members)
}

/// Asserts that the Rust layout `rust` (from [`rust_layout!`]) mirrors WGSL struct `name`.
pub fn assert_mirrors(source: &str, name: &str, rust: (usize, Vec<Field>)) {
    let (wsize, members) = wgsl_layout(source, name);
    let (rsize, fields) = rust;
    assert_eq!(rsize, wsize, "{name}: Rust size {rsize}, WGSL size {wsize}");
    for (m, off, size) in &members {
        let base = m.trim_end_matches(|c: char| c.is_ascii_digit());
        let f = fields
            .iter()
            .find(|f| f.0 == m.as_str())
            .or_else(|| fields.iter().find(|f| f.0 == base))
            .unwrap_or_else(|| panic!("{name}.{m}: no Rust field of that name"));
        let exact = f.0 == m.as_str();
        assert!(
            *off >= f.1 && off + size <= f.1 + f.2 && (!exact || (*off == f.1 && *size == f.2)),
            "{name}.{m}: WGSL bytes {off}..{} but Rust `{}` is at {}..{}",
            off + size,
            f.0,
            f.1,
            f.1 + f.2
        );
    }
    for f in &fields {
        assert!(
            members.iter().any(|m| m.1 == f.1),
            "{name}: Rust field `{}` at {} starts no WGSL member",
            f.0,
            f.1
        );
    }
}
