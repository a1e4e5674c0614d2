//! The database files on disk (issue 16): the WAL stays bounded while overlapping readers keep
//! a passive checkpoint from ever restarting it, and the files are the owner's alone.

use std::path::{Path, PathBuf};
use std::time::Duration;

use mrstudy_server::storage::{Connection, Database, Storage, StudyRecord, WriteJob};

/// A participant-sized write through the writer's queue: one row of `size` bytes.
struct Blob {
    key: u32,
    size: usize,
}

impl WriteJob for Blob {
    type Outcome = ();
    async fn run(&self, connection: &mut Connection) -> Result<(), sqlx::Error> {
        sqlx::query("INSERT OR REPLACE INTO blobs (key, value) VALUES ($1, $2)")
            .bind(i64::from(self.key))
            .bind(vec![self.key as u8; self.size])
            .execute(connection)
            .await?;
        Ok(())
    }
}

fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(suffix);
    PathBuf::from(name)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn the_wal_stays_below_64_mb_while_readers_overlap() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mrstudy.db");
    let storage = Storage::open(&Database::Sqlite(path.clone())).await.unwrap();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    // Two readers, each holding a read transaction 40 ms and starting 20 ms apart: at every
    // moment one of them reads a snapshot in the WAL.
    let mut readers = Vec::new();
    for offset in [0, 20] {
        let pool = storage.read.clone();
        let stop = stop.clone();
        readers.push(tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(offset)).await;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                let mut transaction = pool.begin().await.unwrap();
                let _: i64 =
                    sqlx::query_scalar("SELECT count(*) FROM studies").fetch_one(&mut *transaction).await.unwrap();
                tokio::time::sleep(Duration::from_millis(40)).await;
                transaction.commit().await.unwrap();
            }
        }));
    }
    // 160 writes of 1 MB each through the writer's queue: 160 MB through the WAL.
    sqlx::query("CREATE TABLE blobs (key INTEGER PRIMARY KEY, value BLOB)").execute(&storage.admin).await.unwrap();
    let wal = with_suffix(&path, "-wal");
    let mut largest = 0;
    for key in 0..160u32 {
        storage.write(Blob { key: key % 8, size: 1 << 20 }).await.unwrap();
        largest = largest.max(std::fs::metadata(&wal).map(|meta| meta.len()).unwrap_or(0));
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    for reader in readers {
        reader.await.unwrap();
    }
    assert!(largest < 64 * 1024 * 1024, "the WAL grew to {:.1} MB", largest as f64 / 1048576.0);
    assert!(largest > 0);
}

#[cfg(unix)]
#[tokio::test]
async fn the_database_files_are_readable_by_their_owner_only() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mrstudy.db");
    // a database made by an earlier version, world-readable
    std::fs::write(&path, b"").unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    let storage = Storage::open(&Database::Sqlite(path.clone())).await.unwrap();
    storage
        .upsert_study(&StudyRecord {
            slug: "s",
            title: "S",
            kind: "paired-comparison",
            open: true,
            definition: "{}".into(),
            file_sha256: "0",
        })
        .await
        .unwrap();
    for file in [path.clone(), with_suffix(&path, "-wal"), with_suffix(&path, "-shm")] {
        let mode = std::fs::metadata(&file).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600, "{} has mode {mode:o}", file.display());
    }
    let fresh = dir.path().join("fresh/mrstudy.db");
    drop(Storage::open(&Database::Sqlite(fresh.clone())).await.unwrap());
    assert_eq!(std::fs::metadata(&fresh).unwrap().permissions().mode() & 0o777, 0o600);
}
