"""HTTP API, schemas, auth and the data layer of metairl (never imports torch)."""
