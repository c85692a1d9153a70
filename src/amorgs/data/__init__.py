"""Solution tables: column schema and merging (:mod:`.tables`), atomic IO (:mod:`.io`), the β-filter
(:mod:`.filter`) and per-shard seed derivation (:mod:`.seeds`)."""
