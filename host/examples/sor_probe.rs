use mema::kdtree::KdTree;
fn main() {
    for name in std::env::args().skip(1) {
        let (c, _) = mema::io::load_cloud_in_metres(name.as_ref(), None).unwrap();
        let pts = c.world_points();
        let tree = KdTree::build(&pts);
        let mut out = Vec::new();
        let k = 20;
        let d: Vec<f64> = pts
            .iter()
            .enumerate()
            .map(|(i, p)| {
                tree.k_nearest(*p, Some(i), k, &mut out);
                out.iter().map(|e| e.0.sqrt()).sum::<f64>() / out.len() as f64
            })
            .collect();
        let n = d.len() as f64;
        let mu = d.iter().sum::<f64>() / n;
        let sd = (d.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let mut s = d.clone();
        s.sort_by(|a, b| a.total_cmp(b));
        let med = s[s.len() / 2];
        let mut dev: Vec<f64> = d.iter().map(|x| (x - med).abs()).collect();
        dev.sort_by(|a, b| a.total_cmp(b));
        let mad = dev[dev.len() / 2] * 1.4826;
        let frac = |t: f64| d.iter().filter(|&&x| x > t).count();
        println!(
            "{name}: n {} mu {mu:.4} sd {sd:.4} med {med:.4} mad {mad:.4} max {:.4} | >mu+2sd {} >mu+3sd {} >mu+6sd {} >mu+10sd {} | >med+6mad {} >med+10mad {} | >10med {} >30med {}",
            d.len(),
            s[s.len() - 1],
            frac(mu + 2. * sd),
            frac(mu + 3. * sd),
            frac(mu + 6. * sd),
            frac(mu + 10. * sd),
            frac(med + 6. * mad),
            frac(med + 10. * mad),
            frac(10. * med),
            frac(30. * med)
        );
    }
}
