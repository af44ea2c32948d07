# street_topview.png: the street clip from above. street_topview.py writes its CSVs (not kept in
# the repository: they hold the clip's ground truth, which may not be bundled). Redraw
# from this folder with:  gnuplot street_topview.gp
if (!exists("outfile")) outfile = "street_topview.png"
set terminal pngcairo size 900,760 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set title "karlsruhe_0019_street from above: wallar track (threaded), walls of the last model"
set grid
set size ratio -1
set key top left box opaque
set xlabel "x [m] (right of the first camera)"
set ylabel "z [m] (ahead of the first camera)"
plot "street_topview_walls.csv" skip 1 using 1:2 with lines lw 3 lc rgb "#d95f02" title "walls and floor outlines (last model)", \
     "street_topview_path.csv" skip 1 using 3:4 with lines lw 4 lc rgb "#bbbbbb" title "ground truth (OXTS, aligned)", \
     "" skip 1 using 1:2 with lines lw 1.5 lc rgb "#1b9e77" title "wallar"
