"""The service's database: SQLAlchemy models, CRUD functions (keyword-only, each commits what it
changes), array storage, the file store, sessions and the Alembic migrations (``migrations/``,
shipped in the package). The only code that touches the database."""
