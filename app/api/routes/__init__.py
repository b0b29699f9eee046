"""One router per resource; ``app.api.main`` includes them."""
