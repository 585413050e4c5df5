-- Issue 79: dashboard sessions kept in the database, so that signing out, removing a token, an
-- idle timeout and a lifetime end them. The cookie carries a random id of 256 bits; only its
-- SHA-256 is stored (id_hash), with the name of the token signed in with (the first 16 hex
-- digits of the token's SHA-256, never the token) and its role. A session ended is deleted.
CREATE TABLE sessions (
    id_hash      TEXT COLLATE "C" NOT NULL PRIMARY KEY,
    token_name   TEXT COLLATE "C" NOT NULL,
    role         TEXT COLLATE "C" NOT NULL,
    created_at   TEXT COLLATE "C" NOT NULL,
    last_seen_at TEXT COLLATE "C" NOT NULL
);
CREATE INDEX sessions_last_seen ON sessions (last_seen_at);
