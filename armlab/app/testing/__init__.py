"""What only the tests and the benches use: a headless client that speaks the page's
websocket protocol without a browser."""
