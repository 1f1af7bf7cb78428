//! ROS 2 bags in sqlite3 storage (`rosbag2_storage_default_plugins`' `.db3` files, the default before
//! Iron): a `topics` table (`id`, `name`, `type`, `serialization_format`) and a `messages` table
//! (`topic_id`, `timestamp` in nanoseconds, `data` as CDR), read with `rusqlite` and its bundled SQLite.
//!
//! Messages are read in receive-time order a page of rows at a time (keyed on `timestamp, id`), so memory
//! stays at one page whatever the bag's size.

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rusqlite::{Connection as Database, OpenFlags};

use crate::connection::{Connection, MessageReader, RawMessage};
use crate::error::BagError;
use crate::wire::Encoding;

/// The first bytes of every SQLite 3 database.
pub const MAGIC: &[u8] = b"SQLite format 3\0";

/// Rows fetched per query.
const PAGE_ROWS: i64 = 64;

/// Streams the messages of one `.db3` file.
pub struct SqliteReader {
    path: PathBuf,
    database: Database,
    topics: HashMap<i64, Arc<Connection>>,
    selected_ids: Option<Vec<i64>>,
    /// The `(timestamp, id)` of the last row returned.
    cursor: (i64, i64),
    page: VecDeque<RawMessage>,
    finished: bool,
}

fn database_error(path: &Path, error: rusqlite::Error) -> BagError {
    BagError::malformed(path, 0, format!("sqlite3: {error}"))
}

impl SqliteReader {
    /// Opens the database read-only and reads its `topics` table.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let database = Database::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(|e| database_error(path, e))?;
        let mut topics = HashMap::new();
        {
            let mut statement = database
                .prepare("SELECT id, name, type, serialization_format FROM topics")
                .map_err(|e| database_error(path, e))?;
            let rows = statement
                .query_map([], |row| {
                    Ok((
                        row.get::<_, i64>(0)?,
                        row.get::<_, String>(1)?,
                        row.get::<_, String>(2)?,
                        row.get::<_, String>(3)?,
                    ))
                })
                .map_err(|e| database_error(path, e))?;
            for row in rows {
                let (id, name, message_type, format) = row.map_err(|e| database_error(path, e))?;
                let encoding = match format.as_str() {
                    "cdr" => Encoding::Cdr,
                    "ros1" => Encoding::Ros1,
                    other => {
                        return Err(BagError::unsupported(
                            path,
                            format!("topic {name} is serialized as `{other}`; SKiD reads cdr and ros1"),
                        ));
                    }
                };
                topics.insert(
                    id,
                    Arc::new(Connection::new(&name, &message_type, String::new(), encoding)),
                );
            }
        }
        Ok(Self {
            path: path.to_owned(),
            database,
            topics,
            selected_ids: None,
            cursor: (i64::MIN, i64::MIN),
            page: VecDeque::new(),
            finished: false,
        })
    }

    fn fetch_page(&mut self) -> Result<(), BagError> {
        let filter = match &self.selected_ids {
            Some(ids) if ids.is_empty() => {
                self.finished = true;
                return Ok(());
            }
            Some(ids) => {
                let list: Vec<String> = ids.iter().map(i64::to_string).collect();
                format!("AND topic_id IN ({})", list.join(","))
            }
            None => String::new(),
        };
        let sql = format!(
            "SELECT id, topic_id, timestamp, data FROM messages \
             WHERE (timestamp > ?1 OR (timestamp = ?1 AND id > ?2)) {filter} \
             ORDER BY timestamp, id LIMIT {PAGE_ROWS}"
        );
        let path = self.path.clone();
        let mut statement = self
            .database
            .prepare_cached(&sql)
            .map_err(|e| database_error(&path, e))?;
        let rows = statement
            .query_map([self.cursor.0, self.cursor.1], |row| {
                Ok((
                    row.get::<_, i64>(0)?,
                    row.get::<_, i64>(1)?,
                    row.get::<_, i64>(2)?,
                    row.get::<_, Vec<u8>>(3)?,
                ))
            })
            .map_err(|e| database_error(&path, e))?;
        let mut fetched = 0;
        for row in rows {
            let (id, topic_id, timestamp, data) = row.map_err(|e| database_error(&path, e))?;
            fetched += 1;
            self.cursor = (timestamp, id);
            let Some(connection) = self.topics.get(&topic_id) else {
                return Err(BagError::malformed(
                    &path,
                    0,
                    format!("message {id} refers to topic id {topic_id}, which is not in the topics table"),
                ));
            };
            let Ok(log_time_nanos) = u64::try_from(timestamp) else {
                return Err(BagError::malformed(
                    &path,
                    0,
                    format!("message {id} has a negative timestamp {timestamp}"),
                ));
            };
            self.page.push_back(RawMessage {
                connection: Arc::clone(connection),
                log_time_nanos,
                data: data.into(),
            });
        }
        if fetched < PAGE_ROWS {
            self.finished = true;
        }
        Ok(())
    }
}

impl MessageReader for SqliteReader {
    fn connections(&self) -> Vec<Arc<Connection>> {
        let mut topics: Vec<_> = self.topics.iter().collect();
        topics.sort_by_key(|(id, _)| **id);
        topics.into_iter().map(|(_, c)| Arc::clone(c)).collect()
    }

    fn select_topics(&mut self, topics: &[String]) {
        self.selected_ids = Some(
            self.topics
                .iter()
                .filter(|(_, connection)| topics.contains(&connection.topic))
                .map(|(id, _)| *id)
                .collect(),
        );
    }

    fn next_message(&mut self) -> Result<Option<RawMessage>, BagError> {
        if self.page.is_empty() && !self.finished {
            self.fetch_page()?;
        }
        Ok(self.page.pop_front())
    }
}
