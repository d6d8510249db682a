"""The Celery app and the job runner that feeds the database's jobs to metairl_engine."""
