cylinder(d=6, h=20, $fn=120);
