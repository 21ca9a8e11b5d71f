use super::*;

fn geokeys(keys: &[[u16; 4]]) -> Vec<u8> {
    let mut shorts = vec![1, 1, 0, keys.len() as u16];
    for k in keys {
        shorts.extend_from_slice(k);
    }
    shorts.iter().flat_map(|s| s.to_le_bytes()).collect()
}

#[test]
fn geokeys_give_feet_degrees_and_metres() {
    let feet = geokeys(&[[1024, 0, 1, 1], [3076, 0, 1, 9002]]);
    assert_eq!(
        from_geokeys(&feet, None),
        Some(FileUnit::Length {
            unit: LengthUnit::new("foot", 0.3048),
            source: "LAS GeoKeys"
        })
    );
    let degrees = geokeys(&[[1024, 0, 1, 2], [2054, 0, 1, 9102]]);
    assert!(matches!(
        from_geokeys(&degrees, None),
        Some(FileUnit::Geographic { .. })
    ));
    let us = geokeys(&[[1024, 0, 1, 1], [3076, 0, 1, 9003]]);
    let Some(FileUnit::Length { unit, .. }) = from_geokeys(&us, None) else {
        panic!()
    };
    assert_eq!(unit.metres, 1200.0 / 3937.0);
    let user = geokeys(&[[1024, 0, 1, 1], [3076, 0, 1, 32767], [3077, 34736, 1, 1]]);
    let doubles: Vec<u8> = [0.0f64, 0.25]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    let Some(FileUnit::Length { unit, .. }) = from_geokeys(&user, Some(&doubles)) else {
        panic!()
    };
    assert_eq!(unit.metres, 0.25);
    assert_eq!(from_geokeys(&geokeys(&[[3076, 0, 1, 9002]]), None), None);
    assert_eq!(from_geokeys(&[1, 0], None), None);
}

#[test]
fn wkt_projected_geographic_and_compound() {
    let autzen = r#"PROJCS["NAD_1983_HARN_Lambert_Conformal_Conic",GEOGCS["GCS_North_American_1983_HARN",DATUM["NAD83",SPHEROID["GRS_1980",6378137,298.257222101]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic_2SP"],PARAMETER["false_easting",4921250],UNIT["foot",0.3048,AUTHORITY["EPSG","9002"]]]"#;
    let Some(FileUnit::Length { unit, .. }) = from_wkt(autzen) else {
        panic!()
    };
    assert_eq!((unit.name.as_str(), unit.metres), ("foot", 0.3048));
    let wgs84 = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;
    assert!(matches!(from_wkt(wgs84), Some(FileUnit::Geographic { .. })));
    let compound = format!(
        r#"COMPD_CS["x",{},VERT_CS["NAVD88",VERT_DATUM["x",2005],UNIT["metre",1]]]"#,
        autzen
    );
    let Some(FileUnit::Length { unit, .. }) = from_wkt(&compound) else {
        panic!()
    };
    assert_eq!(unit.metres, 0.3048);
    let wkt2 = r#"PROJCRS["NAD83 / x (ftUS)",BASEGEOGCRS["NAD83",DATUM["x",ELLIPSOID["GRS 1980",6378137,298.257222101,LENGTHUNIT["metre",1]]],ANGLEUNIT["degree",0.0174532925199433]],CONVERSION["x",METHOD["TM"],PARAMETER["False easting",1640416.667,LENGTHUNIT["US survey foot",0.304800609601219]]],CS[Cartesian,2],AXIS["easting (X)",east,ORDER[1],LENGTHUNIT["US survey foot",0.304800609601219]],AXIS["northing (Y)",north,ORDER[2],LENGTHUNIT["US survey foot",0.304800609601219]]]"#;
    let Some(FileUnit::Length { unit, .. }) = from_wkt(wkt2) else {
        panic!("{:?}", from_wkt(wkt2))
    };
    assert_eq!(unit.name, "US survey foot");
    assert_eq!(from_wkt("garbage [[["), None);
    assert_eq!(from_wkt(""), None);
}

#[test]
fn resolving() {
    let feet = FileUnit::Length {
        unit: LengthUnit::new("foot", 0.3048),
        source: "LAS GeoKeys",
    };
    let u = resolve("a", Some(&feet), None).unwrap();
    assert_eq!(u.to_string(), "foot (LAS GeoKeys)");
    let u = resolve("a", None, None).unwrap();
    assert_eq!(u.to_string(), "metre (assumed; --units to change)");
    let mm = LengthUnit::parse("mm").unwrap();
    let u = resolve("a", Some(&feet), Some(&mm)).unwrap();
    assert_eq!(u.to_string(), "millimetre (--units)");
    let geo = FileUnit::Geographic {
        unit: "degrees".into(),
        source: "LAS WKT",
    };
    let e = resolve("a.las", Some(&geo), None).unwrap_err().to_string();
    assert!(
        e.starts_with("a.las: the coordinates are geographic"),
        "{e}"
    );
    for c in LengthUnit::CHOICES {
        assert!(LengthUnit::parse(c).is_some(), "{c}");
    }
    assert!(LengthUnit::parse("furlong").is_none());
}
