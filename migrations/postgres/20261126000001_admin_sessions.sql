-- Admin sessions (issue 16), as ../20261126000001_admin_sessions.sql for sqlite: the SHA-256
-- of a session id and its expiry (Unix seconds), shared by every server process.
CREATE TABLE admin_sessions (
    id_sha256    BYTEA PRIMARY KEY,
    expires_unix BIGINT NOT NULL
);
