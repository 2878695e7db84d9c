"""Tables of results: named columns (NumPy arrays, or lists of str) with their units.

The bodies, the time series, the size distribution, the snapshots, the collision log and
an ensemble's summaries all come back as a :class:`Table`; each converts to what the
analysis needs. pandas, polars and pyarrow are optional: a conversion imports its
library only when called.
"""

from __future__ import annotations

import csv
import os
from typing import Dict, Iterator, Mapping, Optional

import numpy as np


class Table:
    """Named columns of equal length, with units (SI; ``-`` for a pure number)."""

    def __init__(self, name: str, columns: Mapping[str, object], units: Optional[Mapping[str, str]] = None):
        self.name = name
        self.columns: Dict[str, object] = dict(columns)
        units = dict(units or {})
        self.units: Dict[str, str] = {c: units.get(c, "") for c in self.columns}
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError(f"table {name}: columns of different lengths {sorted(lengths)}")

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, column: str):
        try:
            return self.columns[column]
        except KeyError:
            raise KeyError(
                f"table {self.name} has no column `{column}` (columns: {', '.join(self.columns)})"
            ) from None

    def __contains__(self, column: str) -> bool:
        return column in self.columns

    def __iter__(self) -> Iterator[str]:
        return iter(self.columns)

    def keys(self):
        return self.columns.keys()

    def __repr__(self) -> str:
        cols = ", ".join(f"{c} [{u}]" if u and u != "-" else c for c, u in self.units.items())
        return f"<agglo.Table {self.name}: {len(self)} rows; {cols}>"

    def to_numpy(self) -> np.ndarray:
        """A structured array, one field per column (text as unicode)."""
        arrays = []
        for c, v in self.columns.items():
            a = np.asarray(v)
            if a.dtype == object:
                a = a.astype(str)
            arrays.append((c, a))
        dtype = [(c, a.dtype) for c, a in arrays]
        out = np.empty(len(self), dtype=dtype)
        for c, a in arrays:
            out[c] = a
        return out

    def to_pandas(self):
        """A pandas DataFrame (the units in ``df.attrs["units"]``); needs pandas."""
        import pandas as pd

        df = pd.DataFrame({c: v for c, v in self.columns.items()})
        df.attrs["units"] = dict(self.units)
        df.attrs["table"] = self.name
        return df

    def to_polars(self):
        """A polars DataFrame; needs polars."""
        import polars as pl

        return pl.DataFrame({c: (v if isinstance(v, list) else np.asarray(v)) for c, v in self.columns.items()})

    def to_arrow(self):
        """A pyarrow Table with each column's unit in its field metadata; needs pyarrow."""
        import pyarrow as pa

        fields, arrays = [], []
        for c, v in self.columns.items():
            arr = pa.array(v)
            arrays.append(arr)
            meta = {"unit": self.units.get(c, "")} if self.units.get(c) else None
            fields.append(pa.field(c, arr.type, metadata=meta))
        return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata={"agglo.table": self.name}))

    def to_parquet(self, path: "str | os.PathLike[str]") -> None:
        """Write a Parquet file (units in the field metadata); needs pyarrow."""
        import pyarrow.parquet as pq

        pq.write_table(self.to_arrow(), os.fspath(path))

    def to_csv(self, path: "str | os.PathLike[str]") -> None:
        """Write a CSV file: a header line, floats in shortest round-trip form."""
        names = list(self.columns)
        cols = [self.columns[c] for c in names]
        with open(path, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(names)
            for i in range(len(self)):
                w.writerow([_cell(col[i]) for col in cols])


def _cell(x) -> str:
    if isinstance(x, (float, np.floating)):
        return repr(float(x))
    if isinstance(x, (np.integer,)):
        return str(int(x))
    return str(x)


def units_of(table: str) -> Dict[str, str]:
    """The units of an output table's columns (``agglo schema --outputs``)."""
    from . import _agglo

    return dict(_agglo.table_units(table))
