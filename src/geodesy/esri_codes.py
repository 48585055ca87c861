"""Writes the table of ESRI's horizontal CRS codes (esri_codes.tsv.gz is
its gzip): each code of PROJ's database as code, name, datum name and the
PROJ string GDAL makes of it. Run with GDAL's Python bindings:
    python3 esri_codes.py /usr/share/proj/proj.db esri_codes.tsv && gzip -9n esri_codes.tsv
"""
import sqlite3, sys
from osgeo import osr
osr.UseExceptions()
db = sqlite3.connect(sys.argv[1])
rows = []
for table in ("projected_crs", "geodetic_crs"):
    extra = " AND type IN ('geographic 2D')" if table == "geodetic_crs" else ""
    for (code,) in db.execute(f"SELECT code FROM {table} WHERE auth_name = 'ESRI'{extra}"):
        s = osr.SpatialReference()
        try:
            s.SetFromUserInput(f"ESRI:{code}")
            proj4 = s.ExportToProj4()
        except Exception:
            continue
        if not proj4.strip():
            continue
        name = s.GetName() or ""
        datum = s.GetAttrValue("DATUM") or ""
        rows.append((int(code), name, datum, proj4.replace(" +type=crs", "").strip()))
rows.sort()
out = open(sys.argv[2], "w")
out.write("# ESRI horizontal CRSs from PROJ's database : code, name, datum, PROJ string\n")
for r in rows:
    out.write("\t".join(map(str, r)) + "\n")
