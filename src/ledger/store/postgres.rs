//! The ledger on a team's PostgreSQL server (`postgres://...`): several ground stations write
//! one ledger. The `postgres` client is blocking (it runs its own runtime), so it is refused on
//! an async runtime's thread rather than left to panic there.

use std::time::Duration;

use postgres::types::{ToSql, Type};
use postgres::{Client, Config, NoTls};

use super::{Cell, Conn, Dialect, Param};

/// How long connecting may take before it is an error (unless the URL says `connect_timeout`).
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// The key of the transaction-level advisory lock that migrations hold (`emplanLG` in ASCII):
/// two ground stations opening a new ledger at once migrate it one after the other.
const SCHEMA_LOCK: i64 = 0x656d_706c_616e_4c47;

pub(super) struct Db {
    client: Client,
    #[cfg(test)]
    changed: u64,
}

/// A connection string with its password (in the authority or as `password=`) hidden.
pub(super) fn without_password(url: &str) -> String {
    let (scheme, rest) = url.split_once("://").unwrap_or(("", url));
    let (authority_end, query_start) =
        (rest.find(['/', '?']).unwrap_or(rest.len()), rest.find('?'));
    let mut out = String::new();
    out.push_str(scheme);
    out.push_str("://");
    let authority = &rest[..authority_end];
    match authority.rsplit_once('@') {
        Some((userinfo, host)) => {
            let user = userinfo.split_once(':').map_or(userinfo, |(u, _)| u);
            out.push_str(user);
            if userinfo.contains(':') {
                out.push_str(":***");
            }
            out.push('@');
            out.push_str(host);
        }
        None => out.push_str(authority),
    }
    match query_start {
        Some(q) if q >= authority_end => {
            out.push_str(&rest[authority_end..q]);
            let params: Vec<String> = rest[q + 1..]
                .split('&')
                .map(|kv| match kv.split_once('=') {
                    Some(("password", _)) => "password=***".to_string(),
                    _ => kv.to_string(),
                })
                .collect();
            out.push('?');
            out.push_str(&params.join("&"));
        }
        _ => out.push_str(&rest[authority_end..]),
    }
    out
}

/// What went wrong, with the server's own message (the client's Display says only "db error").
fn message(e: &postgres::Error) -> String {
    if let Some(db) = e.as_db_error() {
        return format!("{}: {}", db.severity().to_lowercase(), db.message());
    }
    match std::error::Error::source(e) {
        Some(cause) => format!("{e}: {cause}"),
        None => e.to_string(),
    }
}

fn on_async_runtime() -> Result<(), String> {
    if tokio::runtime::Handle::try_current().is_ok() {
        return Err(
            "the PostgreSQL ledger blocks: it must be used off the async runtime \
                    (tokio::task::spawn_blocking)"
                .to_string(),
        );
    }
    Ok(())
}

impl Db {
    pub(super) fn open(url: &str) -> Result<Db, String> {
        on_async_runtime()?;
        let mut config: Config = url.parse().map_err(|e| message(&e))?;
        if config.get_connect_timeout().is_none() {
            config.connect_timeout(CONNECT_TIMEOUT);
        }
        let client = config
            .connect(NoTls)
            .map_err(|e| format!("cannot connect: {}", message(&e)))?;
        Ok(Db {
            client,
            #[cfg(test)]
            changed: 0,
        })
    }

    fn batch(&mut self, sql: &str) -> Result<(), String> {
        on_async_runtime()?;
        self.client.batch_execute(sql).map_err(|e| message(&e))
    }
}

fn bound(params: &[Param]) -> Vec<Box<dyn ToSql + Sync>> {
    params
        .iter()
        .map(|p| -> Box<dyn ToSql + Sync> {
            match p {
                Param::Int(v) => Box::new(*v),
                Param::Real(v) => Box::new(*v),
                Param::Text(v) => Box::new(v.clone()),
            }
        })
        .collect()
}

fn cell(row: &postgres::Row, k: usize) -> Result<Cell, String> {
    let read = |e: postgres::Error| format!("column {k}: {}", message(&e));
    let ty = row.columns()[k].type_().clone();
    let cell = if ty == Type::INT8 {
        row.try_get::<_, Option<i64>>(k)
            .map_err(read)?
            .map(Cell::Int)
    } else if ty == Type::INT4 {
        row.try_get::<_, Option<i32>>(k)
            .map_err(read)?
            .map(|v| Cell::Int(v.into()))
    } else if ty == Type::FLOAT8 {
        row.try_get::<_, Option<f64>>(k)
            .map_err(read)?
            .map(Cell::Real)
    } else if [Type::TEXT, Type::VARCHAR, Type::NAME, Type::BPCHAR].contains(&ty) {
        row.try_get::<_, Option<String>>(k)
            .map_err(read)?
            .map(Cell::Text)
    } else {
        return Err(format!(
            "column {k} is of type {ty}, which the ledger does not read"
        ));
    };
    Ok(cell.unwrap_or(Cell::Null))
}

impl Conn for Db {
    fn dialect(&self) -> Dialect {
        Dialect::Postgres
    }

    fn begin(&mut self) -> Result<(), String> {
        self.batch("BEGIN")
    }

    fn commit(&mut self) -> Result<(), String> {
        self.batch("COMMIT")
    }

    fn rollback(&mut self) -> Result<(), String> {
        self.batch("ROLLBACK")
    }

    fn lock_schema(&mut self) -> Result<(), String> {
        self.batch(&format!("SELECT pg_advisory_xact_lock({SCHEMA_LOCK})"))
    }

    fn execute(&mut self, sql: &str, params: &[Param]) -> Result<u64, String> {
        on_async_runtime()?;
        let values = bound(params);
        let refs: Vec<&(dyn ToSql + Sync)> = values.iter().map(|v| v.as_ref()).collect();
        let n = self.client.execute(sql, &refs).map_err(|e| message(&e))?;
        #[cfg(test)]
        {
            self.changed += n;
        }
        Ok(n)
    }

    fn query(&mut self, sql: &str, params: &[Param]) -> Result<Vec<Vec<Cell>>, String> {
        on_async_runtime()?;
        let values = bound(params);
        let refs: Vec<&(dyn ToSql + Sync)> = values.iter().map(|v| v.as_ref()).collect();
        let rows = self.client.query(sql, &refs).map_err(|e| message(&e))?;
        rows.iter()
            .map(|row| (0..row.len()).map(|k| cell(row, k)).collect())
            .collect()
    }

    #[cfg(test)]
    fn changes(&mut self) -> Result<u64, String> {
        Ok(self.changed)
    }
}
