//! The bearer token that guards everything that changes the vehicle: 32 random bytes from the
//! operating system, written as 64 hexadecimal characters to a file only its owner can read
//! (mode 0600), created when absent. Requests are compared with it in constant time. A token file
//! of the user's own that others may read, or whose token is short, is reported (`weaknesses`).

use std::path::Path;

use super::ServiceError;

/// Tokens shorter than this are reported as weak (a fresh token is 64 characters).
pub const MIN_TOKEN_CHARS: usize = 32;

/// The service's secret.
#[derive(Clone, PartialEq, Eq)]
pub struct Token(String);

impl std::fmt::Debug for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Token(..)")
    }
}

impl Token {
    /// A token from its text (surrounding whitespace ignored); an empty one is refused.
    pub fn new(text: &str) -> Result<Token, ServiceError> {
        let text = text.trim();
        if text.is_empty() || text.len() > 1024 || !text.bytes().all(|b| b.is_ascii_graphic()) {
            return Err(ServiceError::Token {
                file: String::new(),
                reason: "a token is 1 to 1024 printable ASCII characters without spaces".into(),
            });
        }
        Ok(Token(text.to_string()))
    }

    /// A fresh token: 32 random bytes from the operating system, as hex.
    pub fn random() -> Result<Token, ServiceError> {
        let mut bytes = [0u8; 32];
        getrandom::fill(&mut bytes).map_err(|e| ServiceError::Token {
            file: String::new(),
            reason: format!("no randomness from the operating system: {e}"),
        })?;
        Ok(Token(bytes.iter().map(|b| format!("{b:02x}")).collect()))
    }

    /// Reads the token in `path`, or creates the file (mode 0600) with a fresh one when it does
    /// not exist. Returns the token and whether it was created.
    pub fn load_or_create(path: &Path) -> Result<(Token, bool), ServiceError> {
        let error = |reason: String| ServiceError::Token {
            file: path.display().to_string(),
            reason,
        };
        match std::fs::read_to_string(path) {
            Ok(text) => {
                let token = Token::new(&text).map_err(|_| {
                    error("holds no token (expected one line of printable characters)".into())
                })?;
                Ok((token, false))
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let token = Token::random()?;
                if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                    std::fs::create_dir_all(dir).map_err(|e| error(e.to_string()))?;
                }
                write_private(path, &format!("{}\n", token.0)).map_err(|e| error(e.to_string()))?;
                Ok((token, true))
            }
            Err(e) => Err(error(e.to_string())),
        }
    }

    /// The token's text (for the `Authorization: Bearer` header of a client).
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// Whether `offered` is this token, in time that does not depend on where they differ.
    pub fn matches(&self, offered: &str) -> bool {
        constant_time_eq(self.0.as_bytes(), offered.as_bytes())
    }
}

/// What makes the token in `path` weak, one sentence naming the file each: a mode that lets
/// others than its owner read or change it, a token shorter than [`MIN_TOKEN_CHARS`].
pub fn weaknesses(path: &Path, token: &Token) -> Vec<String> {
    #[cfg(unix)]
    let mode = {
        use std::os::unix::fs::PermissionsExt;
        std::fs::metadata(path).ok().map(|m| m.permissions().mode())
    };
    #[cfg(not(unix))]
    let mode = None;
    weaknesses_of(path, mode, token.as_str().chars().count())
}

/// [`weaknesses`] of a file of unix `mode` (None: not known) holding a token of `chars`
/// characters.
fn weaknesses_of(path: &Path, mode: Option<u32>, chars: usize) -> Vec<String> {
    let mut found = Vec::new();
    if let Some(mode) = mode.filter(|m| m & 0o077 != 0) {
        found.push(format!(
            "token file {}: mode {:04o} lets others than its owner read or change it (chmod 600 it)",
            path.display(),
            mode & 0o7777
        ));
    }
    if chars < MIN_TOKEN_CHARS {
        found.push(format!(
            "token file {}: the token is {chars} characters, shorter than {MIN_TOKEN_CHARS} and easier to guess (delete the file to have a fresh one made)",
            path.display()
        ));
    }
    found
}

/// Compares two byte strings in time that depends only on their lengths (a length mismatch is
/// answered at once: the length of a token is not a secret).
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let diff = a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y));
    // Keeps the optimiser from turning the fold into an early exit.
    std::hint::black_box(diff) == 0
}

/// Creates `path` (not existing yet) readable and writable by its owner only.
fn write_private(path: &Path, text: &str) -> std::io::Result<()> {
    use std::io::Write;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(0o600);
    }
    let mut file = options.open(path)?;
    file.write_all(text.as_bytes())?;
    file.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_token_file_is_created_private_with_64_hex_characters_and_read_back() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("sub/token");
        let (token, created) = Token::load_or_create(&path).expect("created");
        assert!(created);
        assert_eq!(token.as_str().len(), 64);
        assert!(token.as_str().bytes().all(|b| b.is_ascii_hexdigit()));
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path)
                .expect("metadata")
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, 0o600);
        }
        let (again, created) = Token::load_or_create(&path).expect("read");
        assert!(!created);
        assert_eq!(again, token);
        assert_ne!(Token::random().expect("random"), token);
    }

    #[test]
    fn only_the_exact_token_matches() {
        let token = Token::new(" abc123\n").expect("token");
        assert!(token.matches("abc123"));
        for wrong in ["abc124", "abc12", "abc1234", "", "ABC123"] {
            assert!(!token.matches(wrong), "{wrong}");
        }
        assert!(Token::new("  \n").is_err());
        assert!(Token::new("two words").is_err());
    }

    #[test]
    fn a_token_file_others_may_read_or_with_a_short_token_is_weak() {
        let path = Path::new("flights/token");
        assert!(weaknesses_of(path, Some(0o100600), 64).is_empty());
        assert!(weaknesses_of(path, Some(0o400), 32).is_empty());
        assert!(weaknesses_of(path, None, 64).is_empty());
        for mode in [0o644, 0o640, 0o604, 0o620, 0o602, 0o100660] {
            let found = weaknesses_of(path, Some(mode), 64);
            assert_eq!(found.len(), 1, "{mode:o}: {found:?}");
            assert!(found[0].contains("flights/token"), "{}", found[0]);
            assert!(found[0].contains("chmod 600"), "{}", found[0]);
        }
        let found = weaknesses_of(path, Some(0o600), 31);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].contains("31 characters"), "{}", found[0]);
        assert_eq!(weaknesses_of(path, Some(0o644), 8).len(), 2);
    }

    #[cfg(unix)]
    #[test]
    fn a_created_token_file_has_no_weakness_and_a_shared_short_one_two() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("token");
        let (token, _) = Token::load_or_create(&path).expect("created");
        assert!(weaknesses(&path, &token).is_empty());
        let shared = dir.path().join("shared");
        std::fs::write(&shared, "secret\n").expect("written");
        std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(0o644)).expect("mode");
        let (token, _) = Token::load_or_create(&shared).expect("read");
        assert_eq!(weaknesses(&shared, &token).len(), 2);
    }

    #[test]
    fn an_empty_token_file_is_an_error_naming_it() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("token");
        std::fs::write(&path, "\n").expect("written");
        let err = Token::load_or_create(&path).expect_err("empty");
        assert!(err.to_string().contains("token"), "{err}");
        assert!(
            err.to_string().contains(&path.display().to_string()),
            "{err}"
        );
    }
}
