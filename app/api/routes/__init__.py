"""One router per resource; :mod:`app.api.main` includes them all."""
