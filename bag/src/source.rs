//! The files of a ROS 2 bag, MCAP or sqlite3, streamed message by message.
//!
//! Only the messages of the wanted topics reach the caller, one at a time, in file order;
//! MCAP is read through the `mcap` crate's sans-I/O linear reader fed from the file in pieces,
//! sqlite3 row by row through a read-only connection, so memory does not grow with the bag.

use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::BagError;

/// The storage format of one bag file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    Mcap,
    Sqlite3,
}

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";
const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// A topic of a bag: its name and message type.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Topic {
    pub name: String,
    pub type_name: String,
}

/// A message of a wanted topic: which of the wanted topics (index), its type, when the bag
/// recorded it (ns), and its serialized bytes.
#[derive(Debug, Clone, Copy)]
pub struct Message<'a> {
    pub topic: usize,
    pub type_name: &'a str,
    pub log_time: i64,
    pub data: &'a [u8],
}

/// How far a pass over the bag has come, in bytes (MCAP) or messages (sqlite3) summed over
/// its files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Position {
    pub done: u64,
    pub total: u64,
}

/// A bag: one file, or the files of a bag folder in recording order.
#[derive(Debug, Clone)]
pub struct Bag {
    pub files: Vec<(PathBuf, Storage)>,
}

/// What a pass saw besides the wanted messages.
#[derive(Debug, Clone, Default)]
pub struct PassSummary {
    /// Every topic the bag declares, in order of appearance.
    pub topics: Vec<Topic>,
    /// Messages of other topics, skipped.
    pub other_messages: u64,
}

impl Bag {
    /// The bag at `path`: an MCAP or sqlite3 file (told by its first bytes), or a bag folder
    /// (`ros2 bag record`'s output), whose `.mcap` or `.db3` files are read in the order of
    /// the split index rosbag2 appends to their names (`name_0`, `name_1`, ...).
    pub fn open(path: &Path) -> Result<Bag, BagError> {
        let input = |message: String| BagError::Input {
            path: path.to_path_buf(),
            message,
        };
        let meta = std::fs::metadata(path).map_err(|e| input(format!("cannot be read: {e}")))?;
        let paths = if meta.is_dir() {
            let entries = std::fs::read_dir(path).map_err(|e| input(format!("cannot be listed: {e}")))?;
            let mut files: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "mcap" || x == "db3") && p.is_file())
                .collect();
            if files.is_empty() {
                return Err(input("is a folder without a .mcap or .db3 bag file".into()));
            }
            files.sort_by_key(|p| (split_index(p), p.clone()));
            files
        } else {
            vec![path.to_path_buf()]
        };
        let files = paths
            .into_iter()
            .map(|p| {
                armcomp_core::support::io::check_input_file(&p).map_err(|m| BagError::Input {
                    path: p.clone(),
                    message: m,
                })?;
                let storage = storage_of(&p)?;
                Ok((p, storage))
            })
            .collect::<Result<Vec<_>, BagError>>()?;
        Ok(Bag { files })
    }

    /// Streams the messages of `topics` to `each` in file order, reporting `progress`; an
    /// error of `each` stops the pass and is returned. `max_record` caps one record's size
    /// (bytes), so that a corrupt length cannot ask for all the memory.
    pub fn stream(
        &self,
        topics: &[&str],
        max_record: u64,
        progress: &mut dyn FnMut(Position),
        each: &mut dyn FnMut(Message<'_>) -> Result<(), BagError>,
    ) -> Result<PassSummary, BagError> {
        let mut summary = PassSummary::default();
        let mut position = Position { done: 0, total: 0 };
        for (path, storage) in &self.files {
            position.total += match storage {
                Storage::Mcap => std::fs::metadata(path).map_or(0, |m| m.len()),
                Storage::Sqlite3 => sqlite_count(path, topics)?,
            };
        }
        for (path, storage) in &self.files {
            match storage {
                Storage::Mcap => stream_mcap(path, topics, max_record, &mut position, progress, each, &mut summary)?,
                Storage::Sqlite3 => stream_sqlite(path, topics, &mut position, progress, each, &mut summary)?,
            }
        }
        Ok(summary)
    }
}

/// The split index rosbag2 appends to a bag file's name (`run_3.mcap` → 3), or 0.
fn split_index(path: &Path) -> u64 {
    path.file_stem()
        .and_then(|s| s.to_str())
        .and_then(|s| s.rsplit_once('_'))
        .and_then(|(_, n)| n.parse().ok())
        .unwrap_or(0)
}

fn storage_of(path: &Path) -> Result<Storage, BagError> {
    let mut head = [0u8; 16];
    let mut file = std::fs::File::open(path).map_err(|e| BagError::Input {
        path: path.to_path_buf(),
        message: format!("cannot be opened: {e}"),
    })?;
    let n = read_full(&mut file, &mut head).map_err(|e| BagError::Input {
        path: path.to_path_buf(),
        message: format!("cannot be read: {e}"),
    })?;
    if head[..n].starts_with(MCAP_MAGIC) {
        Ok(Storage::Mcap)
    } else if head[..n].starts_with(SQLITE_MAGIC) {
        Ok(Storage::Sqlite3)
    } else {
        Err(BagError::Input {
            path: path.to_path_buf(),
            message: "is neither an MCAP file nor a sqlite3 database (its first bytes are neither's magic)".into(),
        })
    }
}

/// Reads until `buf` is full or the file ends; the number of bytes read.
fn read_full(file: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

/// What the `mcap` crate's error means for a user, with where in the file it happened.
fn mcap_error(path: &Path, error: mcap::McapError, at: u64) -> BagError {
    use mcap::McapError as E;
    let what = match &error {
        E::UnexpectedEof => format!("is truncated: the file ends in the middle of a record (after {at} bytes)"),
        E::UnexpectedEoc => format!("is corrupt: a chunk ends in the middle of a record (near byte {at})"),
        E::BadMagic => "is corrupt: its MCAP magic bytes are wrong".to_string(),
        E::BadChunkCrc { .. } | E::BadDataCrc { .. } | E::BadSummaryCrc { .. } => {
            format!("is corrupt: a checksum does not match ({error}, near byte {at})")
        }
        E::RecordTooLarge { len, .. } => {
            format!("is corrupt or too large: a record of {len} bytes (near byte {at}) exceeds the input limit")
        }
        _ => format!("is corrupt: {error} (near byte {at})"),
    };
    BagError::Input {
        path: path.to_path_buf(),
        message: what,
    }
}

fn stream_mcap(
    path: &Path,
    topics: &[&str],
    max_record: u64,
    position: &mut Position,
    progress: &mut dyn FnMut(Position),
    each: &mut dyn FnMut(Message<'_>) -> Result<(), BagError>,
    summary: &mut PassSummary,
) -> Result<(), BagError> {
    let mut file = std::fs::File::open(path).map_err(|e| BagError::Input {
        path: path.to_path_buf(),
        message: format!("cannot be opened: {e}"),
    })?;
    let options = LinearReaderOptions::default()
        .with_validate_chunk_crcs(true)
        .with_record_length_limit(usize::try_from(max_record).unwrap_or(usize::MAX));
    let mut reader = LinearReader::new_with_options(options);
    // Schema id → its name (the message type); channel id → the wanted topic's index and type.
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: HashMap<u16, Option<(usize, String)>> = HashMap::new();
    let start = position.done;
    let mut read = 0u64;
    let mut reported = 0u64;
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| mcap_error(path, e, read))? {
            LinearReadEvent::ReadRequest(need) => {
                let n = file.read(reader.insert(need)).map_err(|e| BagError::Input {
                    path: path.to_path_buf(),
                    message: format!("cannot be read: {e}"),
                })?;
                reader.notify_read(n);
                read += n as u64;
                if read - reported >= 1 << 20 {
                    reported = read;
                    position.done = start + read;
                    progress(*position);
                }
            }
            LinearReadEvent::Record { opcode, data } => {
                match mcap::parse_record(opcode, data).map_err(|e| mcap_error(path, e, read))? {
                    Record::Schema { header, .. } => {
                        schemas.insert(header.id, header.name);
                    }
                    Record::Channel(c) => {
                        let type_name = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                        if !summary.topics.iter().any(|t| t.name == c.topic) {
                            summary.topics.push(Topic {
                                name: c.topic.clone(),
                                type_name: type_name.clone(),
                            });
                        }
                        let wanted = topics.iter().position(|t| *t == c.topic);
                        if wanted.is_some() && c.message_encoding != "cdr" {
                            return Err(BagError::Input {
                                path: path.to_path_buf(),
                                message: format!(
                                    "topic `{}` is encoded as `{}`, not `cdr` (ROS 2's serialization)",
                                    c.topic, c.message_encoding
                                ),
                            });
                        }
                        channels.insert(c.id, wanted.map(|k| (k, type_name)));
                    }
                    Record::Message { header, data } => match channels.get(&header.channel_id) {
                        Some(Some((k, type_name))) => each(Message {
                            topic: *k,
                            type_name,
                            log_time: header.log_time as i64,
                            data: &data,
                        })?,
                        Some(None) => summary.other_messages += 1,
                        None => {
                            return Err(BagError::Input {
                                path: path.to_path_buf(),
                                message: format!(
                                    "is corrupt: a message (near byte {read}) names channel {}, which no channel record declared",
                                    header.channel_id
                                ),
                            });
                        }
                    },
                    _ => {}
                }
            }
        }
    }
    position.done = start + read;
    progress(*position);
    Ok(())
}

/// A read-only connection to a bag's database that runs no code of the file's: the schema is
/// not trusted (no functions from views or triggers) and the defensive mode forbids writes to
/// the database's internals.
fn open_sqlite(path: &Path) -> Result<rusqlite::Connection, BagError> {
    let flags = rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let conn = rusqlite::Connection::open_with_flags(path, flags).map_err(|e| sqlite_error(path, e))?;
    conn.set_db_config(rusqlite::config::DbConfig::SQLITE_DBCONFIG_DEFENSIVE, true)
        .map_err(|e| sqlite_error(path, e))?;
    conn.set_db_config(rusqlite::config::DbConfig::SQLITE_DBCONFIG_TRUSTED_SCHEMA, false)
        .map_err(|e| sqlite_error(path, e))?;
    Ok(conn)
}

fn sqlite_error(path: &Path, e: rusqlite::Error) -> BagError {
    let corrupt = matches!(
        e.sqlite_error_code(),
        Some(rusqlite::ErrorCode::DatabaseCorrupt | rusqlite::ErrorCode::NotADatabase)
    );
    BagError::Input {
        path: path.to_path_buf(),
        message: if corrupt {
            format!("is corrupt or truncated: {e}")
        } else {
            format!("cannot be read as a ROS 2 sqlite3 bag (tables `topics` and `messages`): {e}")
        },
    }
}

/// The topics of a sqlite3 bag: (id, name, type) per row of `topics`.
fn sqlite_topics(conn: &rusqlite::Connection, path: &Path) -> Result<Vec<(i64, Topic, String)>, BagError> {
    let mut stmt = conn
        .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
        .map_err(|e| sqlite_error(path, e))?;
    let rows = stmt
        .query_map([], |r| {
            Ok((
                r.get::<_, i64>(0)?,
                Topic {
                    name: r.get(1)?,
                    type_name: r.get(2)?,
                },
                r.get::<_, String>(3)?,
            ))
        })
        .map_err(|e| sqlite_error(path, e))?;
    rows.collect::<Result<Vec<_>, _>>().map_err(|e| sqlite_error(path, e))
}

/// How many messages of `topics` a sqlite3 bag holds (the progress' total), after a check of
/// the database's pages: a truncated or damaged file is named before anything is read.
fn sqlite_count(path: &Path, topics: &[&str]) -> Result<u64, BagError> {
    let conn = open_sqlite(path)?;
    let check: String = conn
        .query_row("PRAGMA quick_check", [], |r| r.get(0))
        .map_err(|e| BagError::Input {
            path: path.to_path_buf(),
            message: format!("is corrupt or truncated: sqlite cannot check its pages ({e})"),
        })?;
    if check != "ok" {
        return Err(BagError::Input {
            path: path.to_path_buf(),
            message: format!("is corrupt or truncated: sqlite's check of its pages says `{check}`"),
        });
    }
    let ids: Vec<i64> = sqlite_topics(&conn, path)?
        .into_iter()
        .filter(|(_, t, _)| topics.contains(&t.name.as_str()))
        .map(|(id, ..)| id)
        .collect();
    let mut n = 0u64;
    for id in ids {
        let count: i64 = conn
            .query_row("SELECT COUNT(*) FROM messages WHERE topic_id = ?1", [id], |r| r.get(0))
            .map_err(|e| sqlite_error(path, e))?;
        n += count.max(0) as u64;
    }
    Ok(n)
}

fn stream_sqlite(
    path: &Path,
    topics: &[&str],
    position: &mut Position,
    progress: &mut dyn FnMut(Position),
    each: &mut dyn FnMut(Message<'_>) -> Result<(), BagError>,
    summary: &mut PassSummary,
) -> Result<(), BagError> {
    let conn = open_sqlite(path)?;
    // Topic id → the wanted topic's index and type.
    let mut wanted: HashMap<i64, (usize, String)> = HashMap::new();
    for (id, topic, format) in sqlite_topics(&conn, path)? {
        if let Some(k) = topics.iter().position(|t| *t == topic.name) {
            if format != "cdr" {
                return Err(BagError::Input {
                    path: path.to_path_buf(),
                    message: format!(
                        "topic `{}` is serialized as `{format}`, not `cdr` (ROS 2's serialization)",
                        topic.name
                    ),
                });
            }
            wanted.insert(id, (k, topic.type_name.clone()));
        }
        if !summary.topics.iter().any(|t| t.name == topic.name) {
            summary.topics.push(topic);
        }
    }
    let others: i64 = conn
        .query_row("SELECT COUNT(*) FROM messages", [], |r| r.get(0))
        .map_err(|e| sqlite_error(path, e))?;
    // The ids are the database's own integers: the query is built from no text of the file.
    let ids: Vec<String> = wanted.keys().map(|id| id.to_string()).collect();
    let query = format!(
        "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({}) ORDER BY id",
        ids.join(",")
    );
    let mut stmt = conn.prepare(&query).map_err(|e| sqlite_error(path, e))?;
    let mut rows = stmt.query([]).map_err(|e| sqlite_error(path, e))?;
    let mut seen = 0i64;
    while let Some(row) = rows.next().map_err(|e| sqlite_error(path, e))? {
        let id: i64 = row.get(0).map_err(|e| sqlite_error(path, e))?;
        let Some((k, type_name)) = wanted.get(&id) else {
            continue;
        };
        seen += 1;
        let log_time: i64 = row.get(1).map_err(|e| sqlite_error(path, e))?;
        let data = row
            .get_ref(2)
            .and_then(|v| v.as_blob().map_err(rusqlite::Error::from))
            .map_err(|e| sqlite_error(path, e))?;
        each(Message {
            topic: *k,
            type_name,
            log_time,
            data,
        })?;
        position.done += 1;
        if position.done.is_multiple_of(4096) {
            progress(*position);
        }
    }
    summary.other_messages += (others - seen).max(0) as u64;
    progress(*position);
    Ok(())
}
