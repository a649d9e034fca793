//! A write killed midway leaves the previous file intact; a corrupted blob is refused with a
//! message that names the file.

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use neusample_precompute::util::io::{atomic_write, atomic_write_with, read_blob};

const CHILD_ENV: &str = "NEUSAMPLE_SAFE_WRITE_CHILD";

/// Runs only as the child process of `killed_write_leaves_old_file_intact`: writes a large
/// file slowly, so that the parent can kill it midway.
#[test]
fn child_slow_writer() {
    let Ok(path) = std::env::var(CHILD_ENV) else {
        return;
    };
    atomic_write_with(&PathBuf::from(path), |w| {
        for _ in 0..10_000 {
            w.write_all(&[0xAB; 4096])?;
            w.flush()?;
            std::thread::sleep(Duration::from_millis(2));
        }
        Ok(())
    })
    .unwrap();
}

#[test]
fn killed_write_leaves_old_file_intact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("blob.bin");
    let old = b"the previous, good content".to_vec();
    atomic_write(&path, &old).unwrap();

    let mut child = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_slow_writer",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_ENV, &path)
        .spawn()
        .unwrap();
    // Wait until the child's temporary file has grown past a few hundred KB.
    let t0 = Instant::now();
    loop {
        let grown = std::fs::read_dir(dir.path()).unwrap().flatten().any(|e| {
            e.file_name().to_string_lossy().ends_with(".tmp")
                && e.metadata().map(|m| m.len() > 300_000).unwrap_or(false)
        });
        if grown {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "child never started writing"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    let _ = child.wait();
    assert_eq!(
        std::fs::read(&path).unwrap(),
        old,
        "old file damaged by a killed write"
    );
}

#[test]
fn corrupted_blob_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cosine.nsb");
    let mut bytes =
        neusample::BlobWriter::new(neusample::SamplerKind::Cosine, neusample::DType::F32, "x")
            .to_bytes();
    atomic_write(&path, &bytes).unwrap();
    assert!(read_blob(&path).is_ok());
    let n = bytes.len();
    bytes[n - 6] ^= 0x10;
    atomic_write(&path, &bytes).unwrap();
    let msg = format!("{:#}", read_blob(&path).unwrap_err());
    assert!(msg.contains("cosine.nsb"), "{msg}");
    assert!(msg.contains("checksum"), "{msg}");
}

#[cfg(unix)]
#[test]
fn new_files_are_world_readable_and_replacements_keep_their_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("new.bin");
    atomic_write(&path, b"a").unwrap();
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o644);
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
    atomic_write(&path, b"b").unwrap();
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640);
}
