//! ESRI's CRS codes (`ESRI:102022`): PROJ's database holds them, this
//! build a table made from it (`esri_codes.py` writes it), unpacked on the
//! first ESRI code a run reads.

use std::io::Read;
use std::sync::OnceLock;

/// One ESRI CRS: its name, datum name and PROJ definition.
pub struct EsriCrs {
    pub name: String,
    pub datum: String,
    pub proj4: String,
}

fn table() -> &'static str {
    static TABLE: OnceLock<String> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut text = String::new();
        flate2::read::GzDecoder::new(&include_bytes!("esri_codes.tsv.gz")[..]).read_to_string(&mut text).expect("the built-in ESRI table unpacks");
        text
    })
}

/// The ESRI CRS of `code`, where the table has it.
pub fn lookup(code: u32) -> Option<EsriCrs> {
    let key = format!("{code}\t");
    let line = table().lines().find(|l| l.starts_with(&key))?;
    let mut f = line.split('\t').skip(1);
    Some(EsriCrs { name: f.next()?.to_string(), datum: f.next()?.to_string(), proj4: f.next()?.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn africa_albers() {
        let c = lookup(102022).unwrap();
        assert_eq!(c.name, "Africa_Albers_Equal_Area_Conic");
        assert!(c.proj4.starts_with("+proj=aea ") && c.proj4.contains("+lat_1=20 +lat_2=-23"), "{}", c.proj4);
        assert!(lookup(4326).is_none());
        assert!(table().lines().count() > 2000);
    }
}
