"""Services: sessions and what they do with a drive. No FastAPI, no bus library imports."""
