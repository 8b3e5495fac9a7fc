//! The monitor's history: an SQLite file (rusqlite, SQLite compiled in).
//!
//! Tables (schema version 1, in `meta`):
//! - `peak_sets`: every peak set received (source, capture time, how many
//!   peaks, when it arrived);
//! - `peaks`: every resonance received (source, capture time, rank and its
//!   figures), the raw history;
//! - `tracks`: the tracks found per source;
//! - `observations`: each track's observation per peak set, with its z and
//!   whether it was anomalous;
//! - `events`: everything the monitor reported (JSON, as printed).
//!
//! Writes are batched and committed every quarter second (and on exit),
//! in WAL mode: a monitor killed at any moment loses at most the last
//! second, and the file stays valid. The file is opened exclusively: a
//! second monitor on the same file is refused with a message instead of
//! interleaving two histories.

use super::track::{Obs, SourceTracker, Track, TrackConfig};
use crate::engine::{PeakSet, Resonance};
use rusqlite::{params, Connection, OpenFlags};
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const SCHEMA_VERSION: i64 = 1;

/// Why the history file cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("history {}: {message}", path.display())]
pub struct HistoryError {
    pub path: PathBuf,
    pub message: String,
}

/// One write waiting for the next commit.
enum Pending {
    Set {
        source: String,
        t_ns: i64,
        n: usize,
        at_ms: i64,
    },
    Peak {
        source: String,
        t_ns: i64,
        rank: usize,
        p: Resonance,
        at_ms: i64,
    },
    Track {
        source: String,
        track: u32,
        frequency_hz: f64,
    },
    Obs {
        source: String,
        track: u32,
        o: Obs,
    },
    Event {
        source: String,
        track: Option<u32>,
        kind: &'static str,
        json: String,
        at_ms: i64,
    },
}

pub struct History {
    path: PathBuf,
    conn: Connection,
    pending: Vec<Pending>,
    last_commit: Instant,
    /// Rows written since opening (peaks, observations, events).
    pub written: u64,
}

/// The six figures of a resonance, read from columns `at..at + 6` in the
/// order the tables store them.
fn resonance_at(r: &rusqlite::Row<'_>, at: usize) -> rusqlite::Result<Resonance> {
    Ok(Resonance {
        frequency_hz: r.get(at)?,
        frequency_std_hz: r.get(at + 1)?,
        power_db: r.get(at + 2)?,
        prominence_db: r.get(at + 3)?,
        damping_ratio: r.get(at + 4)?,
        damping_ratio_std: r.get(at + 5)?,
    })
}

fn unix_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

impl History {
    /// Opens (or creates) the file and takes it for this process.
    pub fn open(path: &Path) -> Result<History, HistoryError> {
        let err = |m: String| HistoryError {
            path: path.to_path_buf(),
            message: m,
        };
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_WRITE
                | OpenFlags::SQLITE_OPEN_CREATE
                | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(|e| err(format!("cannot open: {e}")))?;
        conn.busy_timeout(Duration::from_millis(500))
            .map_err(|e| err(format!("cannot set a busy timeout: {e}")))?;
        let sql_err = |e: rusqlite::Error| -> HistoryError {
            let m = match e.sqlite_error_code() {
                Some(rusqlite::ErrorCode::DatabaseBusy) | Some(rusqlite::ErrorCode::DatabaseLocked) => {
                    "in use by another process (is another monitor running on it?): SQLite says the database is locked".to_string()
                }
                Some(rusqlite::ErrorCode::NotADatabase) | Some(rusqlite::ErrorCode::DatabaseCorrupt) => {
                    format!("not a usable SQLite database ({e}); move it aside to start a new history")
                }
                _ => format!("{e}"),
            };
            err(m)
        };
        // Exclusive: the lock is taken by the first write below and held.
        conn.pragma_update(None, "locking_mode", "EXCLUSIVE")
            .map_err(sql_err)?;
        conn.pragma_update(None, "journal_mode", "WAL")
            .map_err(sql_err)?;
        conn.pragma_update(None, "synchronous", "NORMAL")
            .map_err(sql_err)?;
        conn.execute_batch(
            "BEGIN IMMEDIATE;
             CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
             CREATE TABLE IF NOT EXISTS peak_sets (
                 id INTEGER PRIMARY KEY, source TEXT NOT NULL, t_ns INTEGER NOT NULL,
                 peaks INTEGER NOT NULL, received_unix_ms INTEGER NOT NULL);
             CREATE TABLE IF NOT EXISTS peaks (
                 id INTEGER PRIMARY KEY, source TEXT NOT NULL, t_ns INTEGER NOT NULL,
                 rank INTEGER NOT NULL, frequency_hz REAL, frequency_std_hz REAL,
                 power_db REAL, prominence_db REAL, damping_ratio REAL,
                 damping_ratio_std REAL, received_unix_ms INTEGER NOT NULL);
             CREATE INDEX IF NOT EXISTS peaks_source ON peaks (source, t_ns);
             CREATE TABLE IF NOT EXISTS tracks (
                 source TEXT NOT NULL, track INTEGER NOT NULL, frequency_hz REAL,
                 PRIMARY KEY (source, track));
             CREATE TABLE IF NOT EXISTS observations (
                 id INTEGER PRIMARY KEY, source TEXT NOT NULL, track INTEGER NOT NULL,
                 t_ns INTEGER NOT NULL, frequency_hz REAL, frequency_std_hz REAL,
                 power_db REAL, prominence_db REAL, damping_ratio REAL,
                 damping_ratio_std REAL, z REAL, anomalous INTEGER NOT NULL);
             CREATE INDEX IF NOT EXISTS observations_track ON observations (source, track, id);
             CREATE TABLE IF NOT EXISTS events (
                 id INTEGER PRIMARY KEY, unix_ms INTEGER NOT NULL, source TEXT NOT NULL,
                 track INTEGER, kind TEXT NOT NULL, json TEXT NOT NULL);
             COMMIT;",
        )
        .map_err(sql_err)?;
        let version: Option<String> = conn
            .query_row("SELECT value FROM meta WHERE key = 'schema'", [], |r| {
                r.get(0)
            })
            .map(Some)
            .or_else(|e| match e {
                rusqlite::Error::QueryReturnedNoRows => Ok(None),
                e => Err(e),
            })
            .map_err(sql_err)?;
        match version {
            None => {
                conn.execute(
                    "INSERT INTO meta (key, value) VALUES ('schema', ?1)",
                    params![SCHEMA_VERSION.to_string()],
                )
                .map_err(sql_err)?;
            }
            Some(v) if v == SCHEMA_VERSION.to_string() => {}
            Some(v) => {
                return Err(err(format!(
                    "schema version {v}; this build reads version {SCHEMA_VERSION}"
                )))
            }
        }
        // A quick check that the pages read (a file damaged in the middle).
        let check: String = conn
            .query_row("PRAGMA quick_check", [], |r| r.get(0))
            .map_err(sql_err)?;
        if check != "ok" {
            return Err(err(format!(
                "damaged ({check}); move it aside to start a new history"
            )));
        }
        Ok(History {
            path: path.to_path_buf(),
            conn,
            pending: Vec::new(),
            last_commit: Instant::now(),
            written: 0,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The trackers as the file left them: each source's tracks with their
    /// last `window` normal observations and whether they were alarmed,
    /// and for a source without tracks yet its last peak sets.
    pub fn load(&self, cfg: &TrackConfig) -> Result<HashMap<String, SourceTracker>, HistoryError> {
        let e = |e: rusqlite::Error| HistoryError {
            path: self.path.clone(),
            message: format!("cannot read: {e}"),
        };
        let mut out: HashMap<String, SourceTracker> = HashMap::new();
        let mut st = self
            .conn
            .prepare("SELECT source, track FROM tracks ORDER BY source, track")
            .map_err(e)?;
        let tracks: Vec<(String, u32)> = st
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
            .map_err(e)?
            .collect::<Result<_, _>>()
            .map_err(e)?;
        let mut obs_q = self
            .conn
            .prepare(
                "SELECT t_ns, frequency_hz, frequency_std_hz, power_db, prominence_db,
                        damping_ratio, damping_ratio_std, z
                 FROM observations WHERE source = ?1 AND track = ?2 AND anomalous = 0
                 ORDER BY id DESC LIMIT ?3",
            )
            .map_err(e)?;
        let mut alarm_q = self
            .conn
            .prepare(
                "SELECT kind FROM events WHERE source = ?1 AND track = ?2
                 AND kind IN ('alarm', 'lost', 'cleared') ORDER BY id DESC LIMIT 1",
            )
            .map_err(e)?;
        for (source, track) in tracks {
            let mut hist: VecDeque<Obs> = obs_q
                .query_map(params![source, track, cfg.window as i64], |r| {
                    Ok(Obs {
                        t_ns: r.get(0)?,
                        peak: resonance_at(r, 1)?,
                        z: r.get(7)?,
                        anomalous: false,
                    })
                })
                .map_err(e)?
                .collect::<Result<_, _>>()
                .map_err(e)?;
            hist.make_contiguous().reverse();
            let last: Option<String> = alarm_q
                .query_row(params![source, track], |r| r.get(0))
                .map(Some)
                .or_else(|x| match x {
                    rusqlite::Error::QueryReturnedNoRows => Ok(None),
                    x => Err(x),
                })
                .map_err(e)?;
            let alarmed = matches!(last.as_deref(), Some("alarm") | Some("lost"));
            let t = out
                .entry(source)
                .or_insert_with(|| SourceTracker::new(cfg.clone()));
            t.established = true;
            t.tracks.push(Track::new(track, hist, alarmed));
        }
        // Sources whose baseline was still being pooled.
        let mut src_q = self
            .conn
            .prepare("SELECT DISTINCT source FROM peak_sets")
            .map_err(e)?;
        let sources: Vec<String> = src_q
            .query_map([], |r| r.get(0))
            .map_err(e)?
            .collect::<Result<_, _>>()
            .map_err(e)?;
        let mut sets_q = self
            .conn
            .prepare(
                "SELECT t_ns, frequency_hz, frequency_std_hz, power_db, prominence_db,
                        damping_ratio, damping_ratio_std
                 FROM peaks WHERE source = ?1 ORDER BY id",
            )
            .map_err(e)?;
        let mut est_q = self
            .conn
            .prepare("SELECT COUNT(*) FROM events WHERE source = ?1 AND kind = 'baseline'")
            .map_err(e)?;
        for source in sources {
            if out.contains_key(&source) {
                continue;
            }
            let done: i64 = est_q.query_row(params![source], |r| r.get(0)).map_err(e)?;
            let mut t = SourceTracker::new(cfg.clone());
            if done > 0 {
                // The baseline found no resonance: nothing is tracked.
                t.established = true;
            } else {
                let rows = sets_q
                    .query_map(params![source], |r| {
                        Ok((r.get::<_, i64>(0)?, resonance_at(r, 1)?))
                    })
                    .map_err(e)?;
                for row in rows {
                    let (t_ns, p) = row.map_err(e)?;
                    match t.pending.last_mut() {
                        Some(s) if s.t_ns == t_ns => s.peaks.push(p),
                        _ => t.pending.push(PeakSet {
                            t_ns,
                            peaks: vec![p],
                        }),
                    }
                }
            }
            out.insert(source, t);
        }
        Ok(out)
    }

    pub fn peak_set(&mut self, source: &str, set: &PeakSet) {
        let at_ms = unix_ms();
        self.pending.push(Pending::Set {
            source: source.to_string(),
            t_ns: set.t_ns,
            n: set.peaks.len(),
            at_ms,
        });
        for (rank, p) in set.peaks.iter().enumerate() {
            self.pending.push(Pending::Peak {
                source: source.to_string(),
                t_ns: set.t_ns,
                rank,
                p: *p,
                at_ms,
            });
        }
    }

    pub fn track(&mut self, source: &str, track: u32, frequency_hz: f64) {
        self.pending.push(Pending::Track {
            source: source.to_string(),
            track,
            frequency_hz,
        });
    }

    pub fn observation(&mut self, source: &str, track: u32, o: Obs) {
        self.pending.push(Pending::Obs {
            source: source.to_string(),
            track,
            o,
        });
    }

    pub fn event(&mut self, source: &str, track: Option<u32>, kind: &'static str, json: String) {
        self.pending.push(Pending::Event {
            source: source.to_string(),
            track,
            kind,
            json,
            at_ms: unix_ms(),
        });
    }

    /// Commits when a quarter second has passed since the last commit.
    pub fn maybe_commit(&mut self) -> Result<(), HistoryError> {
        if self.last_commit.elapsed() >= Duration::from_millis(250) {
            self.commit()?;
        }
        Ok(())
    }

    /// Writes everything pending in one transaction. On failure what was
    /// pending stays pending (the next commit tries again).
    pub fn commit(&mut self) -> Result<(), HistoryError> {
        self.last_commit = Instant::now();
        if self.pending.is_empty() {
            return Ok(());
        }
        let path = self.path.clone();
        let e = |e: rusqlite::Error| HistoryError {
            path: path.clone(),
            message: format!("cannot write: {e}"),
        };
        let tx = self.conn.transaction().map_err(e)?;
        {
            let mut sets = tx
                .prepare_cached(
                    "INSERT INTO peak_sets (source, t_ns, peaks, received_unix_ms) VALUES (?1, ?2, ?3, ?4)",
                )
                .map_err(e)?;
            let mut peak = tx
                .prepare_cached(
                    "INSERT INTO peaks (source, t_ns, rank, frequency_hz, frequency_std_hz, power_db,
                     prominence_db, damping_ratio, damping_ratio_std, received_unix_ms)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
                )
                .map_err(e)?;
            let mut track = tx
                .prepare_cached("INSERT OR REPLACE INTO tracks (source, track, frequency_hz) VALUES (?1, ?2, ?3)")
                .map_err(e)?;
            let mut obs = tx
                .prepare_cached(
                    "INSERT INTO observations (source, track, t_ns, frequency_hz, frequency_std_hz,
                     power_db, prominence_db, damping_ratio, damping_ratio_std, z, anomalous)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)",
                )
                .map_err(e)?;
            let mut event = tx
                .prepare_cached("INSERT INTO events (unix_ms, source, track, kind, json) VALUES (?1, ?2, ?3, ?4, ?5)")
                .map_err(e)?;
            for p in &self.pending {
                match p {
                    Pending::Set {
                        source,
                        t_ns,
                        n,
                        at_ms,
                    } => sets.execute(params![source, t_ns, *n as i64, at_ms]),
                    Pending::Peak {
                        source,
                        t_ns,
                        rank,
                        p,
                        at_ms,
                    } => peak.execute(params![
                        source,
                        t_ns,
                        *rank as i64,
                        p.frequency_hz,
                        p.frequency_std_hz,
                        p.power_db,
                        p.prominence_db,
                        p.damping_ratio,
                        p.damping_ratio_std,
                        at_ms
                    ]),
                    Pending::Track {
                        source,
                        track: t,
                        frequency_hz,
                    } => track.execute(params![source, t, frequency_hz]),
                    Pending::Obs { source, track, o } => obs.execute(params![
                        source,
                        track,
                        o.t_ns,
                        o.peak.frequency_hz,
                        o.peak.frequency_std_hz,
                        o.peak.power_db,
                        o.peak.prominence_db,
                        o.peak.damping_ratio,
                        o.peak.damping_ratio_std,
                        o.z,
                        o.anomalous as i64
                    ]),
                    Pending::Event {
                        source,
                        track,
                        kind,
                        json,
                        at_ms,
                    } => event.execute(params![at_ms, source, track, kind, json]),
                }
                .map_err(e)?;
            }
        }
        tx.commit().map_err(e)?;
        self.written += self.pending.len() as u64;
        self.pending.clear();
        Ok(())
    }
}
