"""``steer-ui``: the browser UI's round-trip latency (network / sampler / drawing) and its load test."""
