-- Rate limits shared by every `serve` process of one PostgreSQL database (issue 46, item 4):
-- the token buckets of server/src/limits.rs. UNLOGGED: a bucket is not worth a WAL record,
-- is lost with a crash (every limit starts full again) and so never reaches pg_wal or a
-- streaming replica. `key` is the SHA-256 of `rate_limit_salt.salt` and the client address or
-- the participant's id and credentials, never the address itself; `at` is the database's
-- clock in Unix seconds at the last take. Rows unused for half an hour are deleted.
-- PostgreSQL only: on sqlite (one process) the buckets are the process's own.

CREATE UNLOGGED TABLE rate_limit_buckets (
    bucket TEXT NOT NULL,
    key BYTEA NOT NULL,
    tokens DOUBLE PRECISION NOT NULL,
    at DOUBLE PRECISION NOT NULL,
    PRIMARY KEY (bucket, key)
);

CREATE TABLE rate_limit_salt (
    only_row BOOLEAN PRIMARY KEY DEFAULT TRUE CHECK (only_row),
    salt BYTEA NOT NULL
);

-- 32 random bytes from the server's strong random source (gen_random_uuid, PostgreSQL 13+)
INSERT INTO rate_limit_salt (salt)
VALUES (uuid_send(gen_random_uuid()) || uuid_send(gen_random_uuid()));
