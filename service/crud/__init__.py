"""The data layer behind the routes: create, read and list resources of one lab; each write commits."""
