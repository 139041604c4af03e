"""The service's tables in the store's SQLite file (schema: :mod:`engine.storage.schema`, migration 2).

One repository per table family: :mod:`app.db.jobs`, :mod:`app.db.records`, :mod:`app.db.diagnoses`,
:mod:`app.db.identifications`. Each opens a connection per call through the
:class:`~engine.storage.PatternStore` of the same file, so they are safe across threads and processes.
"""
