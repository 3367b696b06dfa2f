//! Nothing a user types loses data (issue 16), through the binary: outputs that are inputs are
//! refused with the input untouched byte for byte; symlinks are written through; FIFOs and
//! devices are written in place, never replaced; SIGINT/SIGTERM mid-write leave no temporary
//! file and no output; one grid for the whole sequence; every numeric flag checked with its
//! range; `eval` refuses sources that are not the asset's; no error-level noise on success.

mod common;

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{json, root, vdbcook};
use serde_json::Value;

const FOG: &str = "fixtures/vdb/fog_f32_blosc_mask.vdb";

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// A copy of smoke5 in a temp folder.
fn frames_copy(dir: &Path) -> PathBuf {
    let f = dir.join("frames");
    std::fs::create_dir(&f).unwrap();
    for e in std::fs::read_dir(root().join("fixtures/seq/smoke5")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "vdb") {
            std::fs::copy(&p, f.join(p.file_name().unwrap())).unwrap();
        }
    }
    f
}

/// Names of the files left in `dir` (hidden ones included).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn no_partials(dir: &Path) {
    let left: Vec<String> = names(dir)
        .into_iter()
        .filter(|n| n.contains(".partial"))
        .collect();
    assert!(left.is_empty(), "temporary files left behind: {left:?}");
}

/// Runs, expects failure with `code`, and that stderr contains every one of `want`.
fn refused(args: &[&str], code: i32, want: &[&str]) -> String {
    let (c, _, err) = vdbcook(args);
    assert_eq!(c, code, "{args:?}: {err}");
    for w in want {
        assert!(err.contains(w), "{args:?}: {err:?} lacks {w:?}");
    }
    err
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_is_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let original = std::fs::read(root().join(FOG)).unwrap();
    let me = d.join("self.vdb");
    std::fs::copy(root().join(FOG), &me).unwrap();
    // The same path, a symlink to it, and a hard link to it.
    let sym = d.join("sym.vdbc");
    std::os::unix::fs::symlink(&me, &sym).unwrap();
    let hard = d.join("hard.vdbc");
    std::fs::hard_link(&me, &hard).unwrap();
    for out in [&me, &sym, &hard] {
        refused(
            &["cook", &s(&me), "-o", &s(out)],
            1,
            &["would overwrite the input"],
        );
        assert_eq!(std::fs::read(&me).unwrap(), original, "{out:?}");
    }
    // Frame 1 of a folder input, a new frame-named file in a pattern's folder.
    let frames = frames_copy(d);
    let f1 = frames.join("smoke.0001.vdb");
    let f1_bytes = std::fs::read(&f1).unwrap();
    refused(
        &["cook", &s(&frames), "-o", &s(&f1)],
        1,
        &["would overwrite the input"],
    );
    assert_eq!(std::fs::read(&f1).unwrap(), f1_bytes);
    let pat = s(&frames.join("smoke.####.vdb"));
    let f9 = frames.join("smoke.0009.vdb");
    refused(&["cook", &pat, "-o", &s(&f9)], 1, &["frame set being read"]);
    refused(&["cook", &s(&frames), "-o", &s(&f9)], 1, &["frame folder"]);
    assert!(!f9.exists());
    // The next cook of the set still works: nothing was destroyed.
    json(&["cook", &s(&frames), "-o", &s(&d.join("ok.vdbc")), "--json"]);
    // render: a VDB or an asset as its own output (named .png so only the identity check can
    // refuse it).
    let asset_png = d.join("asset.png");
    json(&["cook", &s(&me), "-o", &s(&asset_png), "--json"]);
    let asset_bytes = std::fs::read(&asset_png).unwrap();
    refused(
        &[
            "render",
            &s(&asset_png),
            "-o",
            &s(&asset_png),
            "--backend",
            "cpu",
        ],
        1,
        &["would overwrite the input"],
    );
    assert_eq!(std::fs::read(&asset_png).unwrap(), asset_bytes);
    no_partials(d);
    no_partials(&frames);
}

#[test]
fn a_symlink_output_is_written_through_to_its_target() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let target = d.join("real.vdbc");
    std::fs::write(&target, b"old").unwrap();
    let link = d.join("link.vdbc");
    std::os::unix::fs::symlink("real.vdbc", &link).unwrap();
    json(&["cook", FOG, "-o", &s(&link), "--json"]);
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    let info = json(&["info", "--json", &s(&target)]);
    assert!(info.is_object());
    // A dangling link: its target is created.
    let dangling = d.join("dangling.vdbc");
    std::os::unix::fs::symlink("new.vdbc", &dangling).unwrap();
    json(&["cook", FOG, "-o", &s(&dangling), "--json"]);
    assert!(std::fs::symlink_metadata(&dangling)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(d.join("new.vdbc").is_file());
    no_partials(d);
}

#[test]
fn a_fifo_output_is_written_in_place_and_stays_a_fifo() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("pipe");
    let st = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(st.success());
    let reader = {
        let f = fifo.clone();
        std::thread::spawn(move || std::fs::read(f).unwrap())
    };
    let (code, _, err) = vdbcook(&["cook", FOG, "-o", &s(&fifo)]);
    assert_eq!(code, 0, "{err}");
    let got = reader.join().unwrap();
    let reg = d.join("a.vdbc");
    json(&["cook", FOG, "-o", &s(&reg), "--json"]);
    assert_eq!(got, std::fs::read(&reg).unwrap(), "the FIFO got the asset");
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    no_partials(d);
}

/// Character devices as outputs: fake `/dev/null` (1,3) and `/dev/full` (1,7) made with mknod in
/// a temp folder where this process may (root with CAP_MKNOD), so a regression cannot destroy
/// the real ones. Renaming over them (the old behaviour) turns them into regular files.
#[test]
fn devices_are_written_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let mk = |name: &str, minor: u32| -> Option<PathBuf> {
        let p = dir.path().join(name);
        let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
        // SAFETY: plain system call on a path we own.
        let r = unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, minor)) };
        (r == 0).then_some(p)
    };
    let is_dev = |p: &Path| {
        std::fs::symlink_metadata(p)
            .unwrap()
            .file_type()
            .is_char_device()
    };
    let Some(null) = mk("null", 3) else {
        eprintln!("skipped: cannot mknod here (not root or no CAP_MKNOD)");
        return;
    };
    let (code, _, err) = vdbcook(&["cook", FOG, "-o", &s(&null)]);
    assert_eq!(code, 0, "{err}");
    assert!(is_dev(&null), "the null device was replaced");
    // render too, although the name has no .png extension.
    let (code, _, err) = vdbcook(&[
        "render",
        "fixtures/seq/smoke5",
        "-o",
        &s(&null),
        "--backend",
        "cpu",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(is_dev(&null));
    let full = mk("full", 7).unwrap();
    refused(
        &["cook", FOG, "-o", &s(&full)],
        1,
        &["No space left on device"],
    );
    assert!(is_dev(&full), "the full device was replaced");
    no_partials(dir.path());
}

/// Starts a cook whose write pauses before the rename, waits for its temporary file, sends
/// `sig`, and checks the exit code, that the temporary file is gone and that no output exists.
fn interrupt_mid_write(sig: libc::c_int, want_code: i32) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("a.vdbc");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .args(["cook", FOG, "-o", &s(&out)])
        .current_dir(root())
        .env("VDBCOOK_TEST_WRITE_DELAY_MS", "20000")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t = Instant::now();
    loop {
        if names(d).iter().any(|n| n.contains(".partial")) {
            break;
        }
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "no temporary file appeared"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: signalling our own child.
    unsafe {
        libc::kill(child.id() as libc::pid_t, sig);
    }
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(want_code), "{status:?}");
    assert!(
        t.elapsed() < Duration::from_secs(15),
        "the signal did not stop it"
    );
    no_partials(d);
    assert!(!out.exists(), "a partial output under the final name");
}

#[test]
fn sigint_mid_write_removes_the_temporary_file() {
    interrupt_mid_write(libc::SIGINT, 130);
}

#[test]
fn sigterm_mid_write_removes_the_temporary_file() {
    interrupt_mid_write(libc::SIGTERM, 143);
}

#[test]
fn a_failed_write_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The output is a folder: refused, folder untouched.
    let folder = d.join("out.vdbc");
    std::fs::create_dir(&folder).unwrap();
    refused(&["cook", FOG, "-o", &s(&folder)], 1, &["is a folder"]);
    assert!(folder.is_dir());
    // The output's folder does not exist: said before any frame is read (no stage ran).
    let missing = d.join("nope").join("a.vdbc");
    let err = refused(
        &["cook", FOG, "-o", &s(&missing)],
        1,
        &["cannot write", "nope"],
    );
    assert!(!err.contains("read, build"), "{err}");
    // render checks before it cooks or traces, report before its cooks.
    let err = refused(
        &["render", FOG, "-o", &s(&d.join("nope").join("a.png"))],
        1,
        &["cannot write", "nope"],
    );
    assert!(!err.contains("wrote"), "{err}");
    no_partials(d);
    assert_eq!(names(d), vec!["out.vdbc".to_string()]);
}

/// Two frames whose only float grids have different names (`density`, `surface`).
fn mixed_grids(d: &Path) -> PathBuf {
    let f = d.join("mixed");
    std::fs::create_dir(&f).unwrap();
    std::fs::copy(
        root().join("fixtures/seq/smoke5/smoke.0001.vdb"),
        f.join("smoke.0001.vdb"),
    )
    .unwrap();
    std::fs::copy(
        root().join("fixtures/vdb/levelset_sphere.vdb"),
        f.join("smoke.0002.vdb"),
    )
    .unwrap();
    f
}

#[test]
fn one_grid_for_the_whole_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let set = mixed_grids(d);
    let out = d.join("a.vdbc");
    let err = refused(
        &["cook", &s(&set), "-o", &s(&out)],
        1,
        &[
            "smoke.0002.vdb",
            "no grid 'density'",
            "--allow-missing-grid",
        ],
    );
    assert!(err.contains("'surface'"), "{err}");
    assert!(!out.exists());
    // --json: kind grid_selection, the file is frame 2.
    let (_, stdout, _) = vdbcook(&["cook", &s(&set), "-o", &s(&out), "--json"]);
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["error"]["kind"], "grid_selection");
    assert!(v["error"]["file"]
        .as_str()
        .unwrap()
        .ends_with("smoke.0002.vdb"));
    // An explicit grid missing from frame 1 is an error naming frame 1.
    refused(
        &["cook", &s(&set), "-o", &s(&out), "--grid", "surface"],
        1,
        &["smoke.0001.vdb", "no grid 'surface'"],
    );
    // Under --allow-missing-grid frame 2 is an empty frame, and the output says so.
    let (code, stdout, err) = vdbcook(&[
        "cook",
        &s(&set),
        "-o",
        &s(&out),
        "--json",
        "--allow-missing-grid",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("cooked as empty frames"), "{err}");
    let c: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(c["frames"], 2);
    assert_eq!(c["grid"], "density");
    assert_eq!(c["missing_grid_frames"].as_array().unwrap().len(), 1);
    let info = json(&["info", "--json", &s(&out)]);
    assert_eq!(info["frames"][1]["active_voxels"], 0, "{info}");
    // eval compares the asset's grid in every frame: frame 2 has none and was cooked empty.
    let e = json(&["eval", "--json", &s(&out), &s(&set)]);
    assert_eq!(e["max_abs"], 0.0, "{e}");
    assert_eq!(e["grid"], "density");
}

#[test]
fn threads_out_of_range_is_a_clear_error_not_a_hang() {
    let t = Instant::now();
    for n in ["100000", "0", "1025"] {
        let err = refused(
            &["--threads", n, "cook", FOG, "-o", "/tmp/never.vdbc"],
            2,
            &["--threads", "1 to 1024"],
        );
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(t.elapsed() < Duration::from_secs(30));
    // The top of the range works.
    let dir = tempfile::tempdir().unwrap();
    json(&[
        "--threads",
        "64",
        "cook",
        FOG,
        "-o",
        &s(&dir.path().join("a.vdbc")),
        "--json",
    ]);
}

#[test]
fn numeric_flags_are_checked_with_their_range() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("a.vdbc"));
    let cases: &[(&[&str], &[&str])] = &[
        (&["--clusters", "0"], &["--clusters 0", "1 to"]),
        (&["--clusters", "99999999999"], &["--clusters", "1 to"]),
        (
            &["--clusters", "4", "--variance-threshold", "nan"],
            &["--variance-threshold", ">= 0"],
        ),
        (
            &["--clusters", "4", "--variance-threshold", "-1"],
            &["--variance-threshold", ">= 0"],
        ),
        (&["--iterations", "3"], &["--iterations", "--clusters"]),
        (
            &["--variance-threshold", "0.5"],
            &["--variance-threshold", "--clusters"],
        ),
        (
            &["--clusters", "4", "--iterations", "0"],
            &["--iterations", "1 to"],
        ),
        (
            &["--max-error", "0"],
            &["--max-error", "> 0", "--format f32"],
        ),
        (&["--max-error", "-1"], &["--max-error", "> 0"]),
        (&["--max-error", "nan"], &["--max-error"]),
        (&["--replace-non-finite", "inf"], &["--replace-non-finite"]),
        (
            &["--bc7-quality", "best"],
            &["--bc7-quality 'best'", "slow"],
        ),
    ];
    for (extra, want) in cases {
        let mut args = vec!["cook", FOG, "-o", &out];
        args.extend_from_slice(extra);
        refused(&args, 2, want);
        // --json: one document, kind `usage`.
        args.push("--json");
        let (_, stdout, _) = vdbcook(&args);
        let v: Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(v["error"]["kind"], "usage", "{extra:?}");
    }
    assert!(!Path::new(&out).exists());
}

#[test]
fn clustering_says_what_it_did() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("a.vdbc"));
    // More clusters than candidates: capped, said on stderr and in the JSON.
    let (code, stdout, err) = vdbcook(&[
        "cook",
        FOG,
        "-o",
        &out,
        "--json",
        "--clusters",
        "100000",
        "--variance-threshold",
        "100",
    ]);
    assert_eq!(code, 0, "{err}");
    let c: Value = serde_json::from_str(&stdout).unwrap();
    let cl = &c["clustering"];
    assert_eq!(cl["clusters_requested"], 100000);
    assert!(cl["clusters"].as_u64().unwrap() <= cl["candidates"].as_u64().unwrap());
    assert!(err.contains("capped"), "{err}");
    // No candidates at all (smoke5 at the default threshold): nothing clustered, and said so
    // with --max-error too.
    let (code, stdout, err) = vdbcook(&[
        "cook",
        "fixtures/seq/smoke5",
        "-o",
        &out,
        "--json",
        "--clusters",
        "100",
        "--max-error",
        "0.01",
    ]);
    assert_eq!(code, 0, "{err}");
    let c: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(c["clustering"]["clusters"], 0);
    assert!(err.contains("nothing was clustered"), "{err}");
    // The human summary shows the clustering line.
    let (_, stdout, _) = vdbcook(&["cook", FOG, "-o", &out, "--clusters", "8"]);
    assert!(stdout.contains("clustering"), "{stdout}");
}

#[test]
fn render_output_format_comes_from_the_extension() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["x.jpg", "x.tiff", "x"] {
        let out = dir.path().join(name);
        refused(
            &[
                "render",
                "fixtures/seq/smoke5",
                "-o",
                &s(&out),
                "--backend",
                "cpu",
            ],
            2,
            &["PNG", ".png"],
        );
        assert!(!out.exists());
    }
    // Upper-case .PNG is a PNG.
    let out = dir.path().join("X.PNG");
    let (code, _, err) = vdbcook(&[
        "render",
        "fixtures/seq/smoke5",
        "-o",
        &s(&out),
        "--backend",
        "cpu",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(&std::fs::read(&out).unwrap()[1..4], b"PNG");
}

#[test]
fn hints_name_only_flags_the_command_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let png = s(&dir.path().join("n.png"));
    // render accepts --replace-non-finite (it cooks VDB input), so its hint is true...
    refused(
        &[
            "render",
            "fixtures/vdb/nan.vdb",
            "-o",
            &png,
            "--backend",
            "cpu",
        ],
        1,
        &["--replace-non-finite"],
    );
    let (code, _, err) = vdbcook(&[
        "render",
        "fixtures/vdb/nan.vdb",
        "-o",
        &png,
        "--backend",
        "cpu",
        "--replace-non-finite",
        "0",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    assert_eq!(code, 0, "{err}");
    // ...report does not, so it must not suggest it.
    let err = refused(
        &[
            "report",
            "fixtures/vdb/nan.vdb",
            "-o",
            &s(&dir.path().join("r")),
            "--quick",
            "--no-gpu",
            "--no-peers",
        ],
        1,
        &["NaN"],
    );
    assert!(!err.contains("--replace-non-finite"), "{err}");
}

#[test]
fn eval_refuses_sources_that_are_not_the_assets() {
    let dir = tempfile::tempdir().unwrap();
    let asset = s(&dir.path().join("s.vdbc"));
    json(&["cook", "fixtures/seq/static3", "-o", &asset, "--json"]);
    let others = [
        "fixtures/seq/smoke5/smoke.0001.vdb",
        "fixtures/seq/smoke5/smoke.0002.vdb",
        "fixtures/seq/smoke5/smoke.0003.vdb",
    ];
    let mut args = vec!["eval", &asset];
    args.extend_from_slice(&others);
    refused(&args, 1, &["do not describe the asset", "--force"]);
    // A different transform (xform fixture of another voxel size) is named as such.
    let one = s(&dir.path().join("one.vdbc"));
    json(&["cook", FOG, "-o", &one, "--json"]);
    refused(
        &["eval", &one, "fixtures/vdb/xform_uniform_scale.vdb"],
        1,
        &["transform"],
    );
    // --grid naming another grid than the asset's.
    refused(
        &["eval", &one, FOG, "--grid", "temperature"],
        1,
        &["not the asset's grid"],
    );
    // --force compares anyway, saying so.
    args.extend_from_slice(&["--force", "--json"]);
    let (code, stdout, err) = vdbcook(&args);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("warning"), "{err}");
    let e: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(e["mismatched_frames"].as_array().unwrap().len(), 3);
    // The right sources still pass.
    let e = json(&["eval", "--json", &asset, "fixtures/seq/static3"]);
    assert_eq!(e["max_abs"], 0.0);
}

#[test]
fn render_json_is_pretty_and_success_has_no_error_noise() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("r.png"));
    let o = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .args([
            "render",
            "fixtures/seq/smoke5",
            "-o",
            &out,
            "--backend",
            "auto",
            "--width",
            "16",
            "--height",
            "16",
            "--json",
        ])
        .current_dir(root())
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        !stderr.to_lowercase().contains("error"),
        "noise on success: {stderr}"
    );
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["output"], out.as_str());
    assert!(stdout.contains("\n  \"output\""), "not pretty: {stdout}");
}
