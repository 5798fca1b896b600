"""Many twins beyond one machine: Monte Carlo of the identified uncertainty (montecarlo),
large synthetic datasets in shards (datasets), diagnoses of a fleet's logs (fleet), each split
into seeded batches that run locally on the batch engine or on a Ray cluster (batches)."""
