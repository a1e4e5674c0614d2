-- Admin sessions (issue 16): a login (`GET /admin/login?token=…`) stores the SHA-256 of its
-- random session id with its expiry (Unix seconds), so that the cookie is valid on every
-- server process that shares the database and survives a restart; logout deletes the row,
-- and each login deletes the expired ones.
CREATE TABLE admin_sessions (
    id_sha256    BLOB PRIMARY KEY NOT NULL,
    expires_unix INTEGER NOT NULL
) STRICT;
