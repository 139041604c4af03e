"""Request (``XCreate``) and response (``XPublic``) models of the HTTP API."""
