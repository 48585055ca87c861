"""Measures a mosaic test's outputs in folder argv[1] with GDAL (numpy):
a.tif (no balance, no blend, least-cost seams, a.geojson, a.json), b.tif
(the defaults), c.tif (no balance, no blend, Voronoi seams, c.geojson),
o<k>.tif (each image rectified alone on the grid a.json gives it),
truth.tif and dem.tif. Prints one JSON object of figures."""
import json, sys, os, subprocess
import numpy as np
from osgeo import gdal, ogr
gdal.UseExceptions()
d = sys.argv[1]
def read(p):
    ds = gdal.Open(p)
    a = ds.ReadAsArray().astype(np.float64)
    if a.ndim == 2: a = a[None]
    m = ds.GetRasterBand(1).GetMaskBand().ReadAsArray() > 0
    return ds, a, m
A, a, am = read(f"{d}/a.tif")
gt = A.GetGeoTransform(); W, H = A.RasterXSize, A.RasterYSize
def labels(geojson):
    drv = gdal.GetDriverByName("MEM")
    L = drv.Create("", W, H, 1, gdal.GDT_Int32)
    L.SetGeoTransform(gt); L.SetProjection(A.GetProjection())
    src = ogr.Open(geojson)
    gdal.RasterizeLayer(L, [1], src.GetLayer(0), options=["ATTRIBUTE=index"])
    return L.ReadAsArray()
L = labels(f"{d}/a.geojson")
rep = json.load(open(f"{d}/a.json"))
out = {}
exact_n = exact_eq = 0
some = np.zeros((H, W), bool); anyvalid = np.zeros((H, W), bool)
for k, im in enumerate(rep["images"]):
    p = f"{d}/o{k+1}.tif"
    if not os.path.exists(p): continue
    ds, o, om = read(p)
    g = ds.GetGeoTransform()
    x = round((g[0] - gt[0]) / gt[1]); y = round((g[3] - gt[3]) / gt[5])
    h, w = om.shape
    sl = (slice(y, y + h), slice(x, x + w))
    sel = (L[sl] == k + 1) & om & am[sl]
    exact_n += sel.sum(); exact_eq += (np.all(a[(slice(None),) + sl] == o, axis=0) & sel).sum()
    some[sl] |= np.all(a[(slice(None),) + sl] == o, axis=0) & om & am[sl]
    anyvalid[sl] |= om
out["own_side_pixels"] = int(exact_n); out["own_side_equal"] = int(exact_eq)
out["valid"] = int(am.sum()); out["valid_from_an_image"] = int((some & am).sum())
out["lost"] = int((anyvalid & ~am).sum())
T = gdal.Open(f"{d}/truth.tif"); t = T.ReadAsArray().astype(np.float64)
out["truth_grid_same"] = T.GetGeoTransform() == gt and T.RasterXSize == W and T.RasterYSize == H
def vs_truth(p):
    _, m, mm = read(p); v = mm & (t.sum(0) > 0)
    return float(np.abs(m - t)[:, v].mean())
def jumps(p, L):
    _, m, mm = read(p)
    j = []; s = []
    for ax in (1, 2):
        d1 = np.abs(np.diff(m, axis=ax)).mean(0)
        lab = np.diff(L, axis=ax - 1) != 0
        ok = (L[:, :-1] > 0) & (L[:, 1:] > 0) if ax == 2 else (L[:-1] > 0) & (L[1:] > 0)
        v = (mm[:, :-1] & mm[:, 1:]) if ax == 2 else (mm[:-1] & mm[1:])
        j.append(d1[lab & ok & v]); s.append(d1[~lab & ok & v])
    return float(np.concatenate(j).mean()), float(np.concatenate(s).mean())
for n in ("a", "b", "v"):
    if n == "v" and not os.path.exists(f"{d}/v.tif"):
        continue
    out[f"{n}_truth_mad"] = vs_truth(f"{d}/{n}.tif")
    out[f"{n}_seam_jump"], out[f"{n}_texture_step"] = jumps(f"{d}/{n}.tif", L)
# Height edges under the seams: least-cost (a) against voronoi (c).
Z = gdal.Warp("", f"{d}/dem.tif", format="MEM", outputBounds=(gt[0], gt[3] + H * gt[5], gt[0] + W * gt[1], gt[3]), xRes=gt[1], yRes=-gt[5], resampleAlg="near").ReadAsArray().astype(np.float64)
def spread(a, r, f):
    o = a.copy()
    for _ in range(r):
        p = np.pad(o, 1, mode="edge")
        o = f.reduce([p[1:-1, 1:-1], p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]])
    return o
r = int(rep["cell_px"])
E = (spread(Z, r, np.maximum) - spread(Z, r, np.minimum)) > 1.5
def on_edges(L):
    lab_h = np.zeros((H, W), bool); lab_h[:, :-1] = (np.diff(L, axis=1) != 0) & (L[:, :-1] > 0) & (L[:, 1:] > 0)
    lab_v = np.zeros((H, W), bool); lab_v[:-1] = (np.diff(L, axis=0) != 0) & (L[:-1] > 0) & (L[1:] > 0)
    seam = lab_h | lab_v
    return float((seam & E).sum() / max(seam.sum(), 1)), int(seam.sum())
out["a_seam_on_height_edges"], out["a_seam_px"] = on_edges(L)
out["c_seam_on_height_edges"], out["c_seam_px"] = on_edges(labels(f"{d}/c.geojson"))
out["edge_share"] = float(E.mean())
print(json.dumps(out))
