"""The reference plant: the full network of the seed integrated offline (BDF2), with its energy ledger."""
